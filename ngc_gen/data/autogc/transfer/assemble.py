"""The whole transfer of a template onto one mesh: skeleton, orientation, match, GCs, refinement,
missing parts, coverage (docs/transfer.md)."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
import trimesh

from ngc_gen.data.autogc.coverage import grow_to_cover, rho_matrix
from ngc_gen.data.autogc.frame import to_template
from ngc_gen.data.autogc.hug import centred_on_held, hug_to_cover, hugged
from ngc_gen.data.autogc.orient import Orientation, parse_axis
from ngc_gen.data.autogc.skeleton import local_thickness, proxy_skeleton
from ngc_gen.data.autogc.template import AT_KEYS, Template, TemplateGC
from ngc_gen.data.autogc.tighten import tighten
from ngc_gen.data.errors import DataError
from ngc_gen.data.mesh.proxy import closed_proxy
from ngc_gen.data.mesh.sampling import gc_membership, sample_surface
from ngc_gen.data.rigs.rig_gcs import OWN_REACH, chain_polyline, template_gc
from ngc_gen.geometry import GeneralizedCylinder, bernstein_basis

from .leg_order import reaches_down
from .match import correspond
from .mirror import mirror_stand_in
from .orientation import choose
from .refine import refine
from .roots import owner_of
from .stray import stray_stand_in
from .transfer_settings import Transfer, TransferSettings
from .verify import verify
from .tree import BodyFrame, Tree, _curve_points, skeleton_tree, surface_share, template_rotation

MISSING_REACH = 1.5  # a missing part reaches the surface nearest its place's end within this x
MISSING_SIGMA = np.array([1.0, 1.0, 2.0])  # how far from its place's end (front, left, up) a
                     # stub may be: up least (a deer's tail sticks up, a horse's hangs)
MISSING_PAST = 0.1   # its length (and that much past it); else it is a quarter of its length
START_REACH = 2.0  # a part on the root reaches back toward its template start by at most this x
                   # its top radius (_reach_back)
REAR_TIE = 0.05    # root parts whose template starts lie this close along the body count as one
                   # row (a pair of hind legs) for _rear_start
FINER = 0.4        # a mesh with parts missing is matched again on spurs this x as long kept


def _straight(tgc: TemplateGC, start: np.ndarray, direction: np.ndarray, length: float,
              radius: float, up: np.ndarray) -> GeneralizedCylinder:
    ctrl = start[None] + np.linspace(0.0, 1.0, tgc.degree + 1)[:, None] * direction[None] * length
    return GeneralizedCylinder.from_dict({
        "name": tgc.name, "curve": {"type": "bezier", "points": ctrl.tolist()},
        "up": _safe_up(up, direction).tolist(),
        "keys": [{"t": float(t), "radii": [radius, radius], "twist": 0.0} for t in tgc.keys],
        "caps": [0.5 * radius, 0.5 * radius]})


def _safe_up(up: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """`up` unless it is along the part (within 2.5 degrees: the frame would be undefined): then
    the world axis least along it. Rarely: every mesh of a folder must keep the template's up
    for one shape-latent layout."""
    d = direction / max(np.linalg.norm(direction), 1e-12)
    u = up / max(np.linalg.norm(up), 1e-12)
    if abs(u @ d) < 0.999:
        return u
    return np.eye(3)[int(np.argmin(np.abs(d)))]


def _reach_back(poly: np.ndarray, to_body, start: np.ndarray, radius: float,
                reach: float | None = None) -> np.ndarray:
    """A part on the root (a leg, the tail, the neck) as a rig has it: its skeleton path begins
    where it leaves the body's surface, a rig's limb at the joint inside (a hip above the
    thigh). The polyline (P, 3) is extended back along its own direction toward the template's
    `start` (body frame), at most START_REACH x its top `radius` (`reach`: at most that)."""
    tan = poly[min(8, len(poly) - 1)] - poly[0]
    tan /= max(float(np.linalg.norm(tan)), 1e-12)
    b0 = to_body(poly[0])
    back = to_body(poly[0] - tan) - b0                   # one world unit back, in body units
    length = float((start - b0) @ back / max(float(back @ back), 1e-12))
    length = min(max(length, 0.0), START_REACH * radius if reach is None else reach)
    if length <= 0.0:
        return poly
    return np.concatenate([np.linspace(poly[0] - length * tan, poly[0], 8)[:-1], poly])


def _rear_start(pl: Placing, n: str, start: np.ndarray) -> np.ndarray | None:
    """Where the rearmost part on the root (its template start behind every other's: the tail)
    starts relative to the found roots of the parts nearest it along the body (the hind legs):
    its template start moved forward by as much as those roots lie ahead of the template's.
    A tail that tapers out of a long body (a crocodile's) leaves the surface far behind the
    hips, while a rig's tail starts just behind them. None: not the rearmost part, no such
    root found, or the roots not ahead of the template's."""
    t = pl.template
    root = t.root
    xs = {g.name: float(g.place["start"][0]) for g in t.gcs if g.parent == root and g.name != n}
    if not xs or start[0] >= min(xs.values()):
        return None
    gap = {m: x - start[0] for m, x in xs.items()}
    near = [m for m in xs if gap[m] <= min(gap.values()) + REAR_TIE and m in pl.paths]
    if not near:
        return None
    found = np.mean([pl.body.to_body(pl.tree.nodes[pl.paths[m][0]])[0] for m in near])
    shift = float(found) - float(np.mean([xs[m] for m in near]))
    return start + np.array([shift, 0.0, 0.0]) if shift > 0.0 else None


def _moved_ends(gc: GeneralizedCylinder, place: dict, n: int = 64) -> np.ndarray:
    """The GC's curve (n, 3) with its ends moved to the template's `start_at` / `end_at`
    (relative coordinates in this GC; template module docstring), each move fading linearly
    along the arc to nothing at the other end."""
    C = _curve_points(gc, n)
    at = np.array([place.get("start_at", (-1.0, 0.0, 0.0)), place.get("end_at", (1.0, 0.0, 0.0))])
    target = np.asarray(gc.to_world(at))
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(C, axis=0), axis=1))]
    w = (arc / max(arc[-1], 1e-12))[:, None]
    return C + (1.0 - w) * (target[0] - C[0]) + w * (target[1] - C[-1])


@dataclass
class Placing:
    """One mesh's transfer under way: its surface samples (N, 3), skeleton tree, body frame,
    the template-to-mesh rotation M of directions, the match (paths, the template GC index of
    every tree node, missing GC names, cost) and the GCs made so far by name."""

    template: Template
    st: TransferSettings
    where: str | None
    surface: np.ndarray
    tree: Tree
    body: BodyFrame
    M: np.ndarray
    paths: dict
    labels: np.ndarray
    missing: list[str]
    cost: float
    floor: float
    gcs: dict = field(default_factory=dict)

    @property
    def owner(self) -> np.ndarray:
        """The template GC index of every surface sample: its nearest tree node's, or a leg's
        when nearer the column up to that leg's joint (``roots``)."""
        return owner_of(self.surface, self.template, self.tree, self.labels, self.body,
                        self.paths)

    def gc(self, tgc: TemplateGC, poly: np.ndarray, own: np.ndarray) -> GeneralizedCylinder:
        """The template GC through polyline `poly` fitted to its samples `own`, its `up` the
        template's turned into this mesh."""
        up = _safe_up(self.M @ np.asarray(tgc.up), poly[-1] - poly[0])
        return template_gc(dataclasses.replace(tgc, up=tuple(up)), poly, own, self.st.margin,
                           self.floor, self.where)


def _check_placed(template: Template) -> None:
    if not template.placed:
        lacking = [g.name for g in template.gcs if g.place is None][:3]
        raise DataError(f"template {template.name} does not say where its parts sit (no `place` "
                        f"for {lacking})", path=template.source, field="place",
                        fix="use a template exported from an annotated mesh (train.py "
                            "stage=annotate annotate.export_template=PATH), e.g. "
                            "datasets/animals/quadruped_transfer.yaml")


def _parts(tree: Tree) -> tuple[list[np.ndarray], list[float]]:
    """The body's branches as parts for ``orient``: their nodes and volumes."""
    ids = np.unique(tree.branch_of[tree.main])
    curves = [tree.nodes[tree.branch_of == b] for b in ids]
    volumes = [float(np.linalg.norm(np.diff(c, axis=0), axis=1).sum()) * tree.branch_r[b] ** 2
               for c, b in zip(curves, ids)]
    return curves, volumes


def _finer(pl: Placing, sk, thick: np.ndarray, samples: np.ndarray) -> None:
    """A mesh with parts missing (a short tail pruned with the spurs) matched once more on a
    finer tree; kept when fewer parts are missing and it passes the template's checks."""
    fine = skeleton_tree(sk, thick, FINER * pl.st.min_branch_length, pl.st.max_gcs)
    try:
        again = correspond(pl.template, fine, pl.body, pl.st, pl.where)
    except DataError:
        return
    held = np.bincount(again[1], weights=surface_share(fine, samples),
                       minlength=len(pl.template.gcs))
    if len(again[2]) < len(pl.missing) and \
            verify(pl.template, again[0], pl.body.to_body(fine.nodes), held, pl.body.half,
                   fine.radius).ok:
        pl.tree, (pl.paths, pl.labels, pl.missing, pl.cost) = fine, again


def _path_gcs(pl: Placing, owner: np.ndarray) -> None:
    """Every matched GC through its skeleton path (step 3)."""
    for g, tgc in enumerate(pl.template.gcs):
        if tgc.name in pl.paths:
            own = pl.surface[owner == g]
            poly = chain_polyline(pl.tree.nodes[pl.paths[tgc.name]], own, tgc.extend)
            pl.gcs[tgc.name] = pl.gc(tgc, poly, own)


def _refined_gcs(pl: Placing, owner: np.ndarray, left: np.ndarray) -> list[str]:
    """The joint refinement (step 4), then each GC refitted through its refined curve, reaching
    back toward its template start (a part on the root) and moved to its calibrated ends;
    returns the matched names."""
    t, names = pl.template, pl.template.names
    matched = [n for n in names if n in pl.gcs]
    parent_ix = [matched.index(t.gc(n).parent) if t.gc(n).parent in matched else -1 for n in matched]
    partner_ix = [matched.index(t.gc(n).symmetric) if t.gc(n).symmetric in matched else -1
                  for n in matched]
    ctrls = [np.asarray(pl.gcs[n].to_dict()["curve"]["points"], dtype=np.float64) for n in matched]
    r0 = [np.array([np.sqrt(np.prod(k["radii"])) for k in pl.gcs[n].to_dict()["keys"]])
          / (1 + pl.st.margin) for n in matched]
    own_of = [pl.surface[owner == names.index(n)] for n in matched]
    ctrls = refine(ctrls, own_of, r0, parent_ix, partner_ix, (pl.body.to_world(np.zeros(3)), left),
                   pl.st.refine_steps, pl.st.seed)
    dense_s = np.linspace(0.0, 1.0, 64)
    root_name = t.root
    for n, c, own, r in zip(matched, ctrls, own_of, r0):
        tgc = t.gc(n)
        poly = bernstein_basis(len(c) - 1, dense_s) @ c
        if tgc.parent == root_name:
            start = np.asarray(tgc.place["start"], dtype=np.float64)
            rear = _rear_start(pl, n, start)
            poly = _reach_back(poly, pl.body.to_body, start if rear is None else rear, float(r[0]),
                               None if rear is None else np.inf)
        pl.gcs[n] = pl.gc(tgc, poly, own)
        if any(k in tgc.place for k in AT_KEYS):  # the annotator's ends
            pl.gcs[n] = pl.gc(tgc, _moved_ends(pl.gcs[n], tgc.place), own)
    return matched


def _missing_gc(pl: Placing, n: str, surface_body: np.ndarray) -> None:
    """A missing part of a pair as its found partner's mirror image where that lies on the
    surface (``mirror``), else a GC from where it would attach to the surface where it would
    end (a stub the skeleton pruned), else a small one at its attachment."""
    tgc = pl.template.gc(n)
    place, body = tgc.place, pl.body
    if tgc.symmetric in pl.gcs and tgc.symmetric not in pl.missing:  # (mirror.py)
        m = mirror_stand_in(pl.gcs[tgc.symmetric], body, n, pl.surface)
        if m is not None:
            pl.gcs[n] = m
            return
    start = body.to_world(np.asarray(place["start"]))
    vec = (np.asarray(place["end"]) - np.asarray(place["start"])) * body.half @ body.R
    length = max(float(np.linalg.norm(vec)), pl.floor)
    p = tgc.parent
    while p is not None and p not in pl.gcs:
        p = pl.template.gc(p).parent
    if p is not None and (reaches_down(place) or pl.template.gc(p).parent is not None):
        # on its parent's curve; an end's part on the root (a tail) where the template starts
        # it: a torso's path runs between the limbs' junctions and may end at the hips, half
        # a body length in front of the rump a tail leaves (its stub then out of reach)
        C = _curve_points(pl.gcs[p])
        start = C[np.argmin(np.linalg.norm(C - start, axis=1))]
    if _end_part(pl.template, tgc):  # over the surface no found GC explains (stray.py)
        gc = stray_stand_in(pl, tgc, start, surface_body)
        if gc is not None:
            pl.gcs[n] = gc
            return
    # the part's stub (a short tail the skeleton pruned) is the surface nearest its place's
    # end: the GC reaches it, within the part's length (else the template's direction)
    off = (surface_body - np.asarray(place["end"])) / MISSING_SIGMA
    tip = pl.surface[np.argmin(np.linalg.norm(off, axis=1))]
    reach = float(np.linalg.norm(tip - start))
    stub = pl.floor < reach <= MISSING_REACH * length
    if stub:
        vec, length = tip - start, reach * (1.0 + MISSING_PAST)
    else:
        length = 0.25 * length
    r = max(place["radius"] * body.half[0] * 0.5, pl.floor)
    pl.gcs[n] = _straight(tgc, start, vec / np.linalg.norm(vec), length, r,
                          pl.M @ np.asarray(tgc.up))
    if stub:  # grown over the surface around its tip (the stub itself)
        near = pl.surface[np.linalg.norm(pl.surface - tip, axis=1) <= 3.0 * r]
        pl.gcs[n] = grow_to_cover([pl.gcs[n]], near)[0]


def _end_part(template: Template, tgc: TemplateGC) -> bool:
    """A part on the root that ends the body (a tail): no leg, no children."""
    root = template.root
    return tgc.parent == root and not reaches_down(tgc.place) and \
        not any(g.parent == tgc.name for g in template.gcs)


def _grown(pl: Placing, owner: np.ndarray) -> list[GeneralizedCylinder]:
    """The GCs in template order grown to cover the surface. Unless `hug` (the older way):
    each grows over its own samples near it first, then every sample left outside goes to the
    relatively nearest GC, whose radii both scale."""
    names, surface = pl.template.names, pl.surface
    ordered = [pl.gcs[n] for n in names]
    if pl.st.hug:
        return _hugging(pl, ordered, owner)
    for g, n in enumerate(names):  # alone first: a GC holds its own samples near it
        own = surface[owner == g]
        if n in pl.missing or not len(own):
            continue
        rho, _ = rho_matrix([ordered[g]], own)
        ordered[g] = grow_to_cover([ordered[g]], own[rho[0] <= OWN_REACH])[0]
    return grow_to_cover(ordered, surface)


def _hugging(pl: Placing, ordered: list[GeneralizedCylinder],
             owner: np.ndarray) -> list[GeneralizedCylinder]:
    """GCs that hug (``hug``): curve and radii from each found part's own slices, each parent
    grown to hold where its children start (children attached), the rest of the surface
    covered at least added volume, then each found part shrunk to the least volume that holds
    what it holds."""
    names, surface = pl.template.names, pl.surface
    found = np.array([n not in pl.missing for n in names])
    ordered = [hugged(gc, surface[owner == g], pl.st.hug_quantile, pl.st.margin, pl.floor)
               if found[g] else gc for g, gc in enumerate(ordered)]
    for g, n in enumerate(names):
        parent = pl.template.gc(n).parent
        if parent is not None:
            p = names.index(parent)
            start = np.asarray(ordered[g].to_world(np.array([[-1.0, 0.0, 0.0]])))
            ordered[p] = hug_to_cover([ordered[p]], start)[0]
    own = np.where((owner >= 0) & found[np.clip(owner, 0, None)], owner, -1)
    fixed = {g for g in range(len(names)) if not found[g]}
    return centred_on_held(tighten(hug_to_cover(ordered, surface, owner=own), surface, own,
                                   fixed=fixed), surface, fixed)


def _covering(pl: Placing, owner: np.ndarray) -> list[GeneralizedCylinder]:
    """The GCs in template order grown to cover (`_grown`); the root must be a tube (step 5),
    judged by its radii as grown (hugging: also before they are refitted)."""
    names = pl.template.names
    root = pl.template.root
    if pl.st.hug and root in pl.paths:
        _check_tube(pl, root, pl.gcs[root])
    ordered = _grown(pl, owner)
    if root in pl.paths:  # and as grown to cover: a seat's torso is wide where it is thin
        _check_tube(pl, root, ordered[names.index(root)])
    return ordered


def _check_tube(pl: Placing, root: str, gc: GeneralizedCylinder) -> None:
    """The template's parts are tubes: a plate (a chair's seat) is no torso."""
    r_gc = float(np.median([np.sqrt(np.prod(k["radii"])) for k in gc.to_dict()["keys"]]))
    tube = float(pl.tree.radius[pl.paths[root]].max()) / max(r_gc, 1e-12)
    if tube < pl.st.min_tube:
        t = pl.template
        raise DataError(f"does not match template {t.name} ({t.source}): its {root} is no "
                        f"tube (inside it at most {tube:.2f} of the {root} GC's radius thick, "
                        f"need {pl.st.min_tube}: a plate or a frame, a chair's seat)",
                        path=pl.where, field="annotate.template",
                        fix="annotate this mesh with a template of its kind (or by hand), or "
                            "lower annotate.min_tube")


def transfer_template(mesh: trimesh.Trimesh, template: Template,
                      settings: TransferSettings | None = None, where: str | None = None,
                      override: Orientation | None = None) -> Transfer:
    """The template's GCs on a (normalised) mesh (module docstring), in the mesh's coordinates;
    `rotation` turns them into the template's frame (``frame.written``). override: the user's
    frame for this mesh (frame.read_override). DataError naming `where` when the mesh does not
    match the template in any orientation."""
    st = settings or TransferSettings.from_yaml()
    _check_placed(template)
    V, F = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)
    pts, _ = sample_surface(V, F, st.samples, np.random.default_rng(st.seed))
    surface = np.concatenate([V, pts])
    proxy = closed_proxy(V, F, resolution=st.resolution, seed=st.seed)
    sk = proxy_skeleton(proxy, backend=st.skeleton)
    thick = np.maximum(local_thickness(sk.nodes, surface), proxy.h)  # (also for the retry)
    tree = skeleton_tree(sk, thick, st.min_branch_length, st.max_gcs)
    up, front = parse_axis(st.up, "annotate.up"), parse_axis(st.front, "annotate.front")
    choice = choose(template, tree, surface, surface_share(tree, pts), st, where, *_parts(tree), up,
                    front, override)
    orientation = choice.trial.orientation
    # the template's up vectors turned into this mesh's frame: written in the template's frame
    # (`rotation`) every mesh's are the template's own (one shape-latent layout)
    pl = Placing(template, st, where, surface, tree, choice.trial.body,
                 template_rotation(template, orientation), *choice.trial.found,
                 floor=1e-3 * float(np.ptp(surface, axis=0).max()))
    if pl.missing:
        _finer(pl, sk, thick, pts)
    owner = pl.owner
    _path_gcs(pl, owner)
    matched = _refined_gcs(pl, owner, orientation.left)
    surface_body = pl.body.to_body(surface) if pl.missing else None
    for n in pl.missing:
        _missing_gc(pl, n, surface_body)
    ordered = _covering(pl, owner)
    pp, _, _ = gc_membership(surface, ordered)
    coverage = float((np.bincount(pp, minlength=len(surface)) > 0).mean())
    return Transfer(gcs=ordered, matched=matched, missing=pl.missing, cost=pl.cost,
                    orientation=orientation, coverage=coverage,
                    rotation=to_template(orientation, Orientation(template.up, template.front)),
                    confidence=choice.confidence, warnings=choice.warnings,
                    source="override" if override is not None else
                    "given" if "given" in orientation.source else "detected")
