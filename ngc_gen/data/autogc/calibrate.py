"""Where an annotator's GC ends sit, measured so a transfer can put them there (docs/transfer.md).

A transfer finds each part on the mesh's skeleton: a leg from where its branch leaves the body
to its foot, a head along the skeleton to the snout. An annotator (a rig, a hand) ends the same
part elsewhere, by a rule the surface does not show: a rig's leg starts at the hip joint inside
the body and ends where its last bone meets the surface, its head ends where the head bone
leaves the skull. The template records that rule per GC end as relative coordinates [u, a, b]
of the transferred GC (``place.start_at`` / ``place.end_at``; the template module's docstring):
the template is transferred onto annotated meshes (only their triangles), the annotated curve
ends are read in the transferred GCs' relative coordinates, and the median over the meshes is
kept. Relative coordinates follow the part (along its curve, across in its radii), so one
rule serves a standing and a galloping leg.
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


def without_ends(template: Template) -> Template:
    """The template with its `start_at` / `end_at` dropped: ends where the skeleton puts them."""
    gcs = tuple(dataclasses.replace(g, place={k: v for k, v in g.place.items() if k not in AT_KEYS})
                if g.place is not None else g for g in template.gcs)
    return dataclasses.replace(template, gcs=gcs)


def calibrate_ends(template: Template,
                   annotated: list[tuple[str, trimesh.Trimesh, list[GeneralizedCylinder]]],
                   settings: TransferSettings | None = None) -> Template:
    """The template with `start_at` / `end_at` per GC: the median over the annotated meshes
    [(name, mesh, its annotated GCs with the template's names)] of where each annotated curve
    end lies in the GC the transfer (without ends) finds. A GC the transfer reported missing,
    or a mesh it refused, does not count; a GC never measured keeps no ends."""
    plain = without_ends(template)
    rel: dict[str, list[np.ndarray]] = {n: [] for n in template.names}
    for name, mesh, truth in annotated:
        by_name = {g.name: g for g in truth}
        lacking = [n for n in template.names if n not in by_name]
        if lacking:
            raise DataError(f"its annotation has no GC {lacking[0]!r} of template "
                            f"{template.name}", path=name, field="gcs",
                            fix="calibrate on meshes annotated with this template")
        try:
            tr = transfer_template(mesh, plain, settings, name)
        except DataError:
            continue
        for g in tr.gcs:
            if g.name in tr.missing:
                continue
            ends = np.asarray(by_name[g.name].to_world(ENDS))
            rel[g.name].append(np.asarray(g.to_relative(ends), dtype=np.float64))
    gcs = []
    for g in plain.gcs:
        if rel[g.name]:
            med = np.median(np.stack(rel[g.name]), axis=0)
            g = dataclasses.replace(g, place={**g.place, "start_at": tuple(med[0]),
                                              "end_at": tuple(med[1])})
        gcs.append(g)
    return dataclasses.replace(template, gcs=tuple(gcs))
