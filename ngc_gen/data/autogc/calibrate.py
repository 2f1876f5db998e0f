"""Where an annotator's GC ends sit, measured so a transfer can put them there (docs/transfer.md).

A transfer finds each part on the mesh's skeleton: a leg from where its branch leaves the body
to its foot, a head along the skeleton to the snout. An annotator (a rig, a hand) ends the same
part elsewhere, by a rule the surface does not show: a rig's leg starts at the hip joint inside
the body and ends where its last bone meets the surface, its head ends where the head bone
leaves the skull. The template records that rule per GC end as relative coordinates [u, a, b]
of the transferred GC (``place.start_at`` / ``place.end_at``; the template module's docstring):
the template is transferred onto annotated meshes (only their triangles), the annotated curve
ends are read in the transferred GCs' relative coordinates, and of those the one that lands
within TOLERANCE of the annotated end on the most meshes is kept (``_best``). Relative
coordinates follow the part (along its curve, across in its radii), so one rule serves a
standing and a galloping leg.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import trimesh

from ngc_gen.data.autogc.template import AT_KEYS, Template
from ngc_gen.data.autogc.transfer import TransferSettings, transfer_template
from ngc_gen.data.errors import DataError
from ngc_gen.geometry import GeneralizedCylinder

ENDS = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])  # a curve's ends, relative coordinates
TOLERANCE = 0.1  # an end this x its part's length from the annotated one counts as right (the
                 # endpoint tolerance docs/transfer.md measures against)


def without_ends(template: Template) -> Template:
    """The template with its `start_at` / `end_at` dropped: ends where the skeleton puts them."""
    gcs = tuple(dataclasses.replace(g, place={k: v for k, v in g.place.items() if k not in AT_KEYS})
                if g.place is not None else g for g in template.gcs)
    return dataclasses.replace(template, gcs=gcs)


def _best(cands: np.ndarray, gcs: list[GeneralizedCylinder], truth: np.ndarray,
          length: np.ndarray) -> np.ndarray:
    """Of the candidate relative coordinates (C, 3), the one that, put in each mesh's
    transferred GC (M of them), lands within TOLERANCE x the annotated part's length (M,) of
    that mesh's annotated end (M, 3) on the most meshes; ties to the lower median distance.
    Annotated ends can cluster in two places (two poses, two species' rigs): their median
    falls between the clusters, near no annotated end; this lands in the larger one."""
    world = np.stack([np.asarray(g.to_world(cands), dtype=np.float64) for g in gcs])  # (M, C, 3)
    err = np.linalg.norm(world - truth[:, None], axis=2) / length[:, None]
    hits = (err <= TOLERANCE).sum(0)
    best = np.flatnonzero(hits == hits.max())
    return cands[best[int(np.argmin(np.median(err[:, best], axis=0)))]]


def _measure(task) -> dict | None:
    """One annotated mesh (a worker's task): per GC the transfer (without ends) found and did
    not report missing, (that GC, the annotated ends (2, 3), the annotated ends in its
    relative coordinates (2, 3), the annotated part's length); None when it was refused."""
    template, settings, name, mesh, truth = task
    by_name = {g.name: g for g in truth}
    try:
        tr = transfer_template(mesh, template, settings, name)
    except DataError:
        return None
    out = {}
    for g in tr.gcs:
        if g.name in tr.missing:
            continue
        truth_gc = by_name[g.name]
        ends = np.asarray(truth_gc.to_world(ENDS), dtype=np.float64)
        out[g.name] = (g, ends, np.asarray(g.to_relative(ends), dtype=np.float64),
                       max(float(truth_gc.length), 1e-12))
    return out


def calibrate_ends(template: Template,
                   annotated: list[tuple[str, trimesh.Trimesh, list[GeneralizedCylinder]]],
                   settings: TransferSettings | None = None,
                   workers: int | None = None) -> Template:
    """The template with `start_at` / `end_at` per GC: over the annotated meshes [(name, mesh,
    its annotated GCs with the template's names)], where each annotated curve end lies in the
    GC the transfer (without ends) finds, as relative coordinates; of those (and their
    per-coordinate median) the one within TOLERANCE of the annotated end on the most meshes
    (`_best`; one mesh: its own). A GC the transfer reported missing, or a mesh it refused,
    does not count; a GC never measured keeps no ends. The meshes are transferred in `workers`
    processes (map_shapes)."""
    from ngc_gen.data.workers import map_shapes

    plain = without_ends(template)
    tasks = []
    for name, mesh, truth in annotated:
        have = {g.name for g in truth}
        lacking = [n for n in template.names if n not in have]
        if lacking:
            raise DataError(f"its annotation has no GC {lacking[0]!r} of template "
                            f"{template.name}", path=name, field="gcs",
                            fix="calibrate on meshes annotated with this template")
        tasks.append((plain, settings, name, mesh, list(truth)))
    seen: dict[str, list[tuple]] = {n: [] for n in template.names}
    for measured in map_shapes(_measure, tasks, workers):
        for n, m in (measured or {}).items():
            seen[n].append(m)
    gcs = []
    for g in plain.gcs:
        if seen[g.name]:
            found, truth, rel, length = zip(*seen[g.name])
            rel, truth, length = np.stack(rel), np.stack(truth), np.asarray(length)
            at = [_best(np.concatenate([rel[:, e], np.median(rel[:, e], axis=0)[None]]),
                        found, truth[:, e], length) for e in (0, 1)]
            g = dataclasses.replace(g, place={**g.place,
                                              "start_at": tuple(float(x) for x in at[0]),
                                              "end_at": tuple(float(x) for x in at[1])})
        gcs.append(g)
    return dataclasses.replace(template, gcs=tuple(gcs))
