"""Templates from annotated meshes: places averaged over the meshes, the tree inferred when there is
no template to follow (docs/transfer.md, "Which template")."""
from __future__ import annotations

import dataclasses

import numpy as np

from ngc_gen.data.autogc.coverage import rho_matrix
from ngc_gen.data.autogc.orient import Orientation
from ngc_gen.data.autogc.template import AT_KEYS, Template, TemplateGC
from ngc_gen.data.errors import DataError
from ngc_gen.geometry import GeneralizedCylinder

from .tree import BodyFrame, _curve_points

TIE_LARGER = 0.05  # an inferred tree's edge to a smaller GC costs up to this much more


def _place_of(gc: GeneralizedCylinder, body: BodyFrame) -> dict:
    d = gc.to_dict()
    ctrl = np.asarray(d["curve"]["points"], dtype=np.float64)
    r = float(np.mean([np.sqrt(np.prod(k["radii"])) for k in d["keys"]]))
    return {"start": body.to_body(ctrl[0]), "end": body.to_body(ctrl[-1]),
            "radius": r / body.half[0]}


def _attachment(gcs: list[GeneralizedCylinder]) -> np.ndarray:
    """(G, G, 2): how far each end (start, end) of GC i lies out of GC j, as its relative
    radius measure in j (rho: <= 1 inside)."""
    ends = np.concatenate([_curve_points(g, 2) for g in gcs])          # (2G, 3): start, end
    rho = rho_matrix(gcs, ends)[0]                                      # (G_j, 2G_i)
    return rho.reshape(len(gcs), len(gcs), 2).transpose(1, 0, 2)


def _inferred_tree(gcs: list[GeneralizedCylinder], body: BodyFrame) -> list[TemplateGC]:
    """Template GCs for annotated GCs without a template. Each child's nearer end lies in its
    parent: the tree is the minimum spanning arborescence (Edmonds), rooted at the largest GC,
    of how far the nearer end of a GC lies out of its parent (relative radii, so an ear's base
    sits in the head, not in the other ear's thin tube; no "parents are larger" rule, so a thin
    neck sits between the torso and a larger head). An end inside several GCs (rho <= 1: a
    rig's shoulder joint high in the chest, where the neck's base is too) hangs on the largest
    of them. Each child starts at the end in its parent (export flips its place to start
    there). Its symmetric partner: the GC whose mirror image across the body's mid-plane lies
    closest."""
    import networkx as nx

    dicts = [g.to_dict() for g in gcs]
    vol = np.array([float(np.ptp(_curve_points(g), axis=0).sum()) * np.mean(
        [np.prod(k["radii"]) for k in d["keys"]]) for g, d in zip(gcs, dicts)])
    root = int(np.argmax(vol))
    curves = [_curve_points(g) for g in gcs]
    G = len(gcs)
    A = _attachment(gcs).min(2)                     # (child, parent): its nearer end's rho
    # inside is inside; among GCs equally close a small tie-breaker toward the larger, far
    # below the gaps that separate real attachments
    W = np.maximum(A, 1.0) + TIE_LARGER * (1.0 - vol / max(vol.max(), 1e-12))[None, :]
    graph = nx.DiGraph()
    graph.add_nodes_from(range(G))
    graph.add_weighted_edges_from((j, i, float(W[i, j])) for i in range(G) for j in range(G)
                                  if i != j and i != root)
    pred = np.full(G, -1)
    for j, i in nx.minimum_spanning_arborescence(graph).edges():
        pred[i] = j
    out = []
    for i, (g, d) in enumerate(zip(gcs, dicts)):
        parent, extend = None, [True, True]
        if i != root and G > 1:
            parent = gcs[int(pred[i])].name
            extend = [False, True]
        mirror = body.to_body(curves[i]) * np.array([1.0, -1.0, 1.0])
        errs = [min(np.abs(body.to_body(c) - mirror).mean(), np.abs(body.to_body(c)[::-1] - mirror).mean())
                if j != i else np.inf for j, c in enumerate(curves)]
        j = int(np.argmin(errs))
        partner = gcs[j].name if errs[j] < 0.1 and np.abs(mirror[:, 1]).mean() > 0.05 else None
        out.append(TemplateGC(g.name, (), (), len(d["curve"]["points"]) - 1,
                              tuple(float(k["t"]) for k in d["keys"]), tuple(d["up"]),
                              tuple(extend), parent, None, partner))
    names = [t.name for t in out]
    for k, t in enumerate(out):  # a partner that does not name this one back: none
        if t.symmetric is not None and out[names.index(t.symmetric)].symmetric != t.name:
            out[k] = dataclasses.replace(t, symmetric=None)
    return out


def export_template(shapes: list[tuple[list[GeneralizedCylinder], np.ndarray, Orientation]],
                    name: str, base: Template | None = None) -> Template:
    """A transfer template from annotated meshes: shapes [(GCs, surface samples (N, 3),
    orientation)], all with the same GC names (e.g. one template's GCs on several meshes);
    places averaged over the shapes. `base`: the template they follow (its tree, joints and
    fields kept, its places replaced); None: the tree inferred from the first shape."""
    gcs0, pts0, or0 = shapes[0]
    names = [g.name for g in gcs0]
    for gcs, _, _ in shapes[1:]:
        if [g.name for g in gcs] != names:
            raise DataError(f"annotated meshes disagree on their GCs ({[g.name for g in gcs]} vs "
                            f"{names})", field="annotate.export_template",
                            fix="export from meshes that share one template")
    inferred = _inferred_tree(gcs0, BodyFrame.of(pts0, or0)) if base is None else None
    places = []
    for gcs, pts, orientation in shapes:
        body = BodyFrame.of(pts, orientation)
        pl = [_place_of(g, body) for g in gcs]
        if inferred is not None:  # each child's place starts at its end in its parent
            A = _attachment(gcs)
            for i, t in enumerate(inferred):
                if t.parent is not None and A[i, names.index(t.parent), 1] < A[i, names.index(t.parent), 0]:
                    pl[i] = {**pl[i], "start": pl[i]["end"], "end": pl[i]["start"]}
        places.append(pl)
    mean = [{"start": tuple(np.mean([p[i]["start"] for p in places], 0)),
             "end": tuple(np.mean([p[i]["end"] for p in places], 0)),
             "radius": float(np.mean([p[i]["radius"] for p in places]))} for i in range(len(names))]
    if base is not None:
        if base.names != names:
            raise DataError(f"the GCs {names} are not template {base.name}'s {base.names}",
                            path=base.source, field="annotate.template",
                            fix="export from meshes annotated with this template")
        # the base's ends (where its annotator ends each part: calibrate) are kept
        tgcs = [dataclasses.replace(g, place={**p, **{k: v for k, v in (g.place or {}).items()
                                                      if k in AT_KEYS}})
                for g, p in zip(base.gcs, mean)]
        frame = base.frame or {"up": tuple(or0.up), "front": tuple(or0.front)}
    else:  # the GCs' up vectors are in the first mesh's frame
        tgcs = [dataclasses.replace(g, place=p) for g, p in zip(inferred, mean)]
        frame = {"up": tuple(or0.up), "front": tuple(or0.front)}
    return Template(name, tuple(tgcs), frame=frame)
