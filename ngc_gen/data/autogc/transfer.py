"""Template transfer: one named GC template on a mesh without a rig (docs/transfer.md).

Pinocchio's two steps (a discrete embedding, then a continuous refinement) on our skeleton:
1. Orientation (``orient``): the mesh's up and front, given or detected; every position below
   is read in the body frame (front, left, up) of the surface's bounding box, divided by its
   half extents, as the template's `place` is.
2. Skeleton tree: closed proxy -> curve skeleton -> branch graph (``skeleton_gcs``' steps), as
   one graph of nodes; its largest piece is the body.
3. Correspondence: the template's leaf GCs (no children) onto the tree's leaves by one optimal
   assignment (Hungarian) with geometric costs: where the tip lies (side included, so a left
   leg cannot take a right foot; half as strict across for a part on the mid-plane), where
   its branch leaves the body (front to back, capped), the direction toward it from its
   branch's root, and its thickness relative to the body's thickest part against the
   template's; any template leaf
   may stay unmatched at ``missing_cost``. Two limbs of one side whose branches leave the body
   in the other order than the template starts them (a gallop's crossed legs) are swapped
   (``_front_to_back``). A second pass gives the limbs left out (a grazing
   head, galloping legs) the free ends left over that lie within their reach: at the limb
   chain's length from where it attaches, on its own side. Still missing: matched once more
   on a finer tree (spurs ``FINER`` x as long kept: a short tail). Tree-consistent by
   construction: a leaf's path toward the template root's place is its own up to where it meets another matched leaf's path (its junction); a chain
   of template GCs above one leaf (neck, head) shares that path by the template's lengths; a
   GC above several matched leaves (a torso) is the longest tree path between its children's
   junctions. Every other skeleton node (ears, antlers) goes to the GC nearest along the tree.
   Too few matched leaves, or a mean cost of the matched ones above ``max_match_cost``: the mesh does not match.
4. GCs: each surface sample belongs to its nearest skeleton node's GC; a GC is the template's
   degree of Bezier through its path (free ends extended to the surface), radii and caps from
   its own samples (``rig_gcs.template_gc``, as for a rig), the template's `up` turned into the
   mesh's frame. A template part the mesh lacks reaches from its attachment to the surface
   nearest where its tip would be (a pruned stub), else it is a small GC at its attachment.
5. Refinement (torch, all GCs at once): control points and per-key radii so each GC's own
   samples lie at its radius from its curve (the union's boundary near the surface, the
   surface inside), children start inside their parents, curves stay smooth and symmetric
   pairs keep one thickness profile (their positions mirror only weakly: a posed animal's legs
   are not mirror images); then radii and caps are refitted to
   the refined curves and coverage is repaired (``coverage.grow_to_cover``) as for a rig.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import torch
import trimesh
from scipy.optimize import linear_sum_assignment
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

from ngc_gen.data.autogc.branches import branch_graph, junction_key
from ngc_gen.data.autogc.coverage import grow_to_cover, rho_matrix
from ngc_gen.data.autogc.choose_frame import choose
from ngc_gen.data.autogc.frame import to_template
from ngc_gen.data.autogc.orient import Orientation, parse_axis
from ngc_gen.data.autogc.skeleton import BACKENDS, local_thickness, proxy_skeleton
from ngc_gen.data.autogc.template import AT_KEYS, Template, TemplateGC
from ngc_gen.data.errors import DataError
from ngc_gen.data.mesh.proxy import closed_proxy
from ngc_gen.data.mesh.sampling import gc_membership, sample_surface
from ngc_gen.data.rigs.rig_gcs import OWN_REACH, chain_polyline, template_gc
from ngc_gen.geometry import GeneralizedCylinder, bernstein_basis

SIGMA_TIP = 0.3    # tip position error (body units) that costs 1
W_DIRECTION = 1.0  # weight of 1 - cos(direction toward the tip)
SIGMA_ATTACH = 0.3  # error (body units, front to back) of where a limb's branch leaves the body
W_ATTACH = 1.0     # weight of that attachment term
MAX_ATTACH = 3.0   # at most this much: a galloping animal's skeleton may join its legs mid-body
W_THICKNESS = 0.5  # weight of log(thickness ratio)^2
W_SYMMETRY = 0.01  # refinement: weight of a symmetric pair's mirror mismatch in position (a
                   # posed animal's legs are not mirrored: at 1 a walking horse's front feet
                   # were pulled to their mirrored mean, 0.25 of the leg's length off each)
W_SYMMETRIC_RADII = 1.0  # and in thickness (log radii per key), which posing keeps
MISSING_REACH = 1.5  # a missing part reaches the surface nearest its place's end within this x
MISSING_SIGMA = np.array([1.0, 1.0, 2.0])  # how far from its place's end (front, left, up) a
                     # stub may be: up least (a deer's tail sticks up, a horse's hangs)
MISSING_PAST = 0.1   # its length (and that much past it); else it is a quarter of its length
START_REACH = 2.0  # a part on the root reaches back toward its template start by at most this x
                   # its top radius (_reach_back)
TIE_LARGER = 0.05  # an inferred tree's edge to a smaller GC costs up to this much more
FINER = 0.4        # a mesh with parts missing is matched again on spurs this x as long kept


@dataclass(frozen=True)
class TransferSettings:
    """How a template is put on a mesh; the defaults are conf/annotate/default.yaml's (a test
    checks they agree). See that file for what each field means."""

    resolution: int = 96
    samples: int = 20000
    skeleton: str = "auto"
    margin: float = 0.05
    min_branch_length: float = 1.0
    max_gcs: int = 24
    seed: int = 0
    up: str = "auto"
    front: str = "auto"
    missing_cost: float = 6.0
    max_match_cost: float = 4.0
    min_matched: float = 0.6
    refine_steps: int = 60
    min_tube: float = 0.22

    def __post_init__(self):
        checks = {"resolution": self.resolution >= 16, "samples": self.samples >= 100,
                  "skeleton": self.skeleton in BACKENDS, "margin": self.margin >= 0,
                  "missing_cost": self.missing_cost > 0, "max_match_cost": self.max_match_cost > 0,
                  "min_matched": 0 <= self.min_matched <= 1, "refine_steps": self.refine_steps >= 0,
                  "min_tube": 0 <= self.min_tube < 1}
        for name, ok in checks.items():
            if not ok:
                raise DataError(f"invalid value {getattr(self, name)!r}", field=f"annotate.{name}",
                                fix="resolution >= 16; samples >= 100; skeleton auto|cgal|voxel; "
                                    "margin >= 0; missing_cost, max_match_cost > 0; min_matched "
                                    "in [0, 1]; refine_steps >= 0; min_tube in [0, 1)")
        for name in ("up", "front"):
            parse_axis(getattr(self, name), f"annotate.{name}")

    @classmethod
    def from_config(cls, d) -> "TransferSettings":
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in dict(d).items() if k in names})


@dataclass
class Transfer:
    """The template's GCs on one mesh (template order) and how they were found."""

    gcs: list[GeneralizedCylinder]
    matched: list[str]
    missing: list[str]
    cost: float
    orientation: Orientation
    coverage: float
    rotation: np.ndarray   # (3, 3): the template's frame = rotation @ this mesh's (frame.py)
    confidence: float      # choose_frame.Choice.confidence
    warnings: list[str]    # a given axis overruled
    source: str            # the frame: detected | given | override


# ---- the body frame ------------------------------------------------------------------------
@dataclass(frozen=True)
class BodyFrame:
    """World <-> body coordinates: body = (world @ R.T - center) / half, R rows front, left,
    up; center, half (3,): the bounding box of the surface in (front, left, up)."""

    R: np.ndarray
    center: np.ndarray
    half: np.ndarray

    @classmethod
    def of(cls, points: np.ndarray, orientation: Orientation) -> "BodyFrame":
        R = orientation.matrix
        B = points @ R.T
        lo, hi = B.min(0), B.max(0)
        return cls(R, (lo + hi) / 2.0, np.maximum((hi - lo) / 2.0, 1e-9))

    def to_body(self, p: np.ndarray) -> np.ndarray:
        return (np.asarray(p) @ self.R.T - self.center) / self.half

    def to_world(self, b: np.ndarray) -> np.ndarray:
        return (np.asarray(b) * self.half + self.center) @ self.R

    def length(self, b_vec: np.ndarray) -> float:
        """World length of a body-frame vector (3,)."""
        return float(np.linalg.norm(np.asarray(b_vec) * self.half))


def template_rotation(template: Template, orientation: Orientation) -> np.ndarray:
    """(3, 3) M turning a direction in the template's frame into the mesh's: M @ v."""
    tf = Orientation(template.up, template.front)
    return orientation.matrix.T @ tf.matrix


# ---- the skeleton tree ---------------------------------------------------------------------
@dataclass
class Tree:
    """nodes (N, 3), radius (N,), graph: (N, N) sparse edge lengths, main (N,) bool: the body's
    piece, branch_of (N,): the branch each node came from, branch_dir (B, 3): unit direction of
    each branch toward its free end (zero for inner branches), branch_r (B,) mean radius,
    branch_root (B, 3): where an end branch leaves the rest (its junction end)."""

    nodes: np.ndarray
    radius: np.ndarray
    graph: object
    main: np.ndarray
    branch_of: np.ndarray
    branch_dir: np.ndarray
    branch_r: np.ndarray
    branch_root: np.ndarray

    @property
    def degree(self) -> np.ndarray:
        return np.diff(self.graph.indptr)


def skeleton_tree(sk, radius: np.ndarray, min_length: float, max_branches: int) -> Tree:
    """The branch tree of a proxy skeleton `sk` (local thickness `radius` per node), spurs
    shorter than min_length x their thickness pruned."""
    branches = branch_graph(sk.nodes, sk.edges, radius, min_length, max_branches)
    key_id: dict = {}
    pts, rad, owner, edges = [], [], [], []
    dirs, mean_r, roots = [], [], []
    n = 0
    for b, br in enumerate(branches):
        ids = []
        for k, (p, r) in enumerate(zip(br.points, br.radius)):
            end = k == 0 or k == len(br.points) - 1
            key = junction_key(p) if end else None
            if key is not None and key in key_id:
                ids.append(key_id[key])
                continue
            pts.append(p)
            rad.append(r)
            owner.append(b)
            if key is not None:
                key_id[key] = n
            ids.append(n)
            n += 1
        edges += list(zip(ids[:-1], ids[1:]))
        d = np.zeros(3)
        if br.junction[0] != br.junction[1] and len(br.points) > 1:
            d = br.points[-1] - br.points[0] if br.junction[0] else br.points[0] - br.points[-1]
            d = d / max(np.linalg.norm(d), 1e-12)
        dirs.append(d)
        roots.append(br.points[0] if br.junction[0] else br.points[-1])
        mean_r.append(float(np.mean(br.radius)))
    P = np.asarray(pts, dtype=np.float64)
    E = np.asarray([e for e in edges if e[0] != e[1]], dtype=np.int64).reshape(-1, 2)
    w = np.linalg.norm(P[E[:, 0]] - P[E[:, 1]], axis=1) + 1e-9
    G = coo_matrix((np.r_[w, w], (np.r_[E[:, 0], E[:, 1]], np.r_[E[:, 1], E[:, 0]])),
                   shape=(n, n)).tocsr()
    _, comp = connected_components(G, directed=False)
    seg = np.zeros(n)
    np.add.at(seg, E[:, 0], w * np.asarray(rad)[E[:, 0]] ** 2)
    weight = np.bincount(comp, weights=seg + np.asarray(rad) ** 3)
    main = comp == int(np.argmax(weight))
    return Tree(P, np.asarray(rad), G, main, np.asarray(owner), np.asarray(dirs),
                np.asarray(mean_r), np.asarray(roots, dtype=np.float64).reshape(-1, 3))


# ---- correspondence ------------------------------------------------------------------------
def _children(template: Template) -> dict[str, list[str]]:
    out = {g.name: [] for g in template.gcs}
    for g in template.gcs:
        if g.parent is not None:
            out[g.parent].append(g.name)
    return out


def _end_children(template: Template, kids: dict) -> dict[str, list[str]]:
    """Each GC's children that attach in the far half of its `place` (its start -> end): the
    ones that continue it (a head on its neck's end), not the side branches (ears near a
    head's base, legs along a torso)."""
    out = {}
    for g in template.gcs:
        a, b = np.asarray(g.place["start"]), np.asarray(g.place["end"])
        d = b - a
        out[g.name] = [c for c in kids[g.name]
                       if (np.asarray(template.gc(c).place["start"]) - a) @ d
                       >= 0.5 * max(float(d @ d), 1e-12)]
    return out


def _tips(template: Template) -> tuple[list[str], dict[str, list[str]], dict[str, list[str]]]:
    """The template GCs with a free tip, put onto the skeleton's free ends: the GCs nothing
    continues (no children in their far half: limbs, and a head with ears near its base), the
    root only when it has no children; each GC's tips at or below it (itself first); the
    continuing children (``_end_children``)."""
    kids = _children(template)
    ends = _end_children(template, kids)
    root = next(g.name for g in template.gcs if g.parent is None)
    tips = [g.name for g in template.gcs if not ends[g.name] and (g.name != root or not kids[root])]
    below: dict[str, list[str]] = {}

    def walk(name):
        if name not in below:
            below[name] = ([name] if name in tips else []) + [x for c in kids[name] for x in walk(c)]
        return below[name]

    for g in template.gcs:
        walk(g.name)
    return tips, below, ends


def match_cost(template: Template, tree: Tree, body: BodyFrame, leaf_gcs: list[str],
               leaves: np.ndarray, reach: bool = False, attach: bool = True) -> np.ndarray:
    """(T, L) cost of template leaf GC t on tree leaf l (module docstring, step 3). reach (the
    second pass, for the limbs the first left out): the tip's position term asks only that it
    lie at the limb's length from where the limb attaches (a posed limb swings about its
    attachment: a grazing head, a galloping leg), on the limb's own side of the body. attach:
    with the term for where the limb's branch leaves the body."""
    tip = body.to_body(tree.nodes[leaves])                          # (L, 3)
    d_mesh = tree.branch_dir[tree.branch_of[leaves]] @ body.R.T / body.half
    d_mesh /= np.maximum(np.linalg.norm(d_mesh, axis=1, keepdims=True), 1e-12)
    # thickness relative to the body's thickest part (a skeleton radius is the inscribed one, a
    # GC's radius the enclosing one: only their ratios to the body compare)
    r_mesh = tree.branch_r[tree.branch_of[leaves]] / float(tree.radius[tree.main].max())
    r_root = max(g.place["radius"] for g in template.gcs)
    at_front = body.to_body(tree.branch_root[tree.branch_of[leaves]])[:, 0]  # (L,)
    C = np.zeros((len(leaf_gcs), len(leaves)))
    for i, name in enumerate(leaf_gcs):
        pl = template.gc(name).place
        end, start = np.asarray(pl["end"]), np.asarray(pl["start"])
        d_t = end - start
        d_t /= max(np.linalg.norm(d_t), 1e-12)
        sigma = np.full(3, SIGMA_TIP)
        if template.gc(name).symmetric is None:  # on the mid-plane: its side hardly tells
            sigma[1] *= 2.0
        chain = _chain(template, name)
        # where its branch leaves the body, front to back, against where any GC of its chain
        # starts (a branch may hold a whole leg, or only a head past its ears): it stays when
        # the limb swings (a galloping front foot behind its shoulder)
        starts = np.array([template.gc(n).place["start"][0] for n in chain])
        att = np.minimum((np.abs(at_front[:, None] - starts[None]).min(1) / SIGMA_ATTACH) ** 2,
                         MAX_ATTACH) if attach else 0.0
        if reach:
            top = chain[-1]                                    # (a head's neck)
            length = sum(np.linalg.norm(np.subtract(template.gc(n).place["end"],
                                                    template.gc(n).place["start"])) for n in chain)
            at = np.linalg.norm(tip - np.asarray(template.gc(top).place["start"]), axis=1)
            side = ((tip[:, 1] - end[1]) / SIGMA_TIP) ** 2 if template.gc(name).symmetric \
                else 0.0
            pos = ((at - length) / SIGMA_TIP) ** 2 + side
        else:
            pos = (((tip - end) / sigma) ** 2).sum(1)
        C[i] = (pos + W_ATTACH * att + W_DIRECTION * (1.0 - d_mesh @ d_t)
                + W_THICKNESS * np.log(np.maximum(r_mesh, 1e-6) / (pl["radius"] / r_root)) ** 2)
    return C


def _front_to_back(template: Template, tree: Tree, body: BodyFrame,
                   assign: dict[str, int]) -> dict[str, int]:
    """Two matched limbs on one side of the body, where the template starts one in front of
    the other (a front and a hind leg) but this mesh's branch for it leaves the body more than
    SIGMA_ATTACH behind the other's: their ends swapped. A gallop's crossed legs put each foot
    at the other's place; where the legs leave the body does not cross."""
    def top(name):
        return (_chain(template, name) or [name])[-1]

    out = dict(assign)
    names = list(out)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            sa, sb = (np.asarray(template.gc(top(n)).place["start"]) for n in (a, b))
            if template.gc(top(a)).parent != template.gc(top(b)).parent or \
                    min(abs(sa[1]), abs(sb[1])) < 0.2 or np.sign(sa[1]) != np.sign(sb[1]):
                continue                                   # not one side's pair
            fa, fb = (body.to_body(tree.branch_root[tree.branch_of[out[n]]])[0] for n in (a, b))
            if (sa[0] - sb[0]) * (fa - fb) < 0 and abs(fa - fb) > SIGMA_ATTACH and \
                    abs(sa[0] - sb[0]) > SIGMA_ATTACH:
                out[a], out[b] = out[b], out[a]
    return out


def _chain(template: Template, name: str) -> list[str]:
    """The GC and its ancestors up to the root's child (the root left out)."""
    return [name, *_ancestors(template, name)][:-1]


def _ancestors(template: Template, name: str) -> list[str]:
    out, p = [], template.gc(name).parent
    while p is not None:
        out.append(p)
        p = template.gc(p).parent
    return out


def _path(pred: np.ndarray, node: int) -> list[int]:
    out = [node]
    while pred[out[-1]] >= 0:
        out.append(int(pred[out[-1]]))
    return out


def _split_by(arc: np.ndarray, fractions: list[float]) -> list[int]:
    """Indices cutting a path with arc lengths `arc` (P,) into pieces of these length shares."""
    cuts = np.cumsum(fractions)[:-1] / max(sum(fractions), 1e-12) * arc[-1]
    return [0] + [int(np.clip(np.searchsorted(arc, c), 1, len(arc) - 2)) for c in cuts] + [len(arc) - 1]


def _bend_near(P: np.ndarray, arc: np.ndarray, i: int, window: float = 0.2) -> int:
    """The index within `window` x the path's length of i where the path (P, 3) bends most
    (the angle between the chords over that window before and after): a neck meets its head
    at a bend, not at a fixed share of the length."""
    w = window * arc[-1]
    cand = np.flatnonzero((np.abs(arc - arc[i]) <= w) & (arc >= w / 2) & (arc <= arc[-1] - w / 2))
    if len(cand) == 0:
        return i
    before = P[cand] - P[np.searchsorted(arc, arc[cand] - w / 2).clip(0, len(P) - 1)]
    after = P[np.searchsorted(arc, arc[cand] + w / 2).clip(0, len(P) - 1)] - P[cand]
    cos = (before * after).sum(1) / np.maximum(
        np.linalg.norm(before, axis=1) * np.linalg.norm(after, axis=1), 1e-12)
    return int(np.clip(cand[int(np.argmin(cos))], 1, len(P) - 2))


def _before_side_branches(path: np.ndarray, arc: np.ndarray, cut: list[int], degree: np.ndarray,
                          window: float = 0.2) -> list[int]:
    """Inner cuts of a chain's path (node indices, junction first) moved to just before the
    first junction of side branches (unmatched ends: ears, horns, antlers) within `window` x
    the path's length of them: what branches off at a neck's top stands out of the head, so the
    junction is the head's, and the side branches, labelled by the nearest GC along the tree,
    are too."""
    side = np.flatnonzero(degree[path] >= 3)
    side = side[(side > 0) & (side < len(path) - 1)]
    out = list(cut)
    for k in range(1, len(out) - 1):
        near = side[np.abs(arc[side] - arc[out[k]]) <= window * arc[-1]]
        if len(near):
            out[k] = int(np.clip(near.min() - 1, out[k - 1] + 1, out[k + 1] - 1))
    return out


def _along_place(path: list[int], nodes: np.ndarray, body: BodyFrame, place: dict) -> list[int]:
    """A path between junctions (a torso) run the way the template's part runs, start to end:
    the longest path between two junctions has no direction of its own."""
    ends = body.to_body(nodes[[path[0], path[-1]]])
    s, e = np.asarray(place["start"]), np.asarray(place["end"])
    kept = np.linalg.norm(ends[0] - s) + np.linalg.norm(ends[1] - e)
    flipped = np.linalg.norm(ends[0] - e) + np.linalg.norm(ends[1] - s)
    return path if kept <= flipped else path[::-1]


def correspond(template: Template, tree: Tree, body: BodyFrame, settings: TransferSettings,
               where: str | None = None) -> tuple[dict[str, np.ndarray], np.ndarray, list[str], float]:
    """Paths (node indices, root side first) of the matched template GCs, the template GC index
    of every tree node (N,), the missing GC names and the mean match cost. DataError (one line)
    when the mesh does not match the template."""
    kids = _children(template)
    leaf_gcs, below, ends = _tips(template)
    names = template.names
    deg = tree.degree
    leaves = np.flatnonzero(tree.main & (deg == 1))
    root_gc = next(g.name for g in template.gcs if g.parent is None)
    if len(leaves) < 2:
        raise DataError(f"its skeleton has {len(leaves)} free ends, nothing to put template "
                        f"{template.name}'s ({template.source}) {len(leaf_gcs)} limbs on",
                        path=where, field="mesh",
                        fix="give this mesh its own annotation, or use a template of its kind")
    T = len(leaf_gcs)

    def assignment(C):
        aug = np.hstack([C, np.where(np.eye(T, dtype=bool), settings.missing_cost, 1e9)])
        rows, cols = linear_sum_assignment(aug)
        return ({leaf_gcs[r]: int(leaves[c]) for r, c in zip(rows, cols) if c < len(leaves)},
                [aug[r, c] for r, c in zip(rows, cols) if c < len(leaves)])

    # whether the mesh matches is judged on the pose terms alone; the assignment also weighs
    # where each branch leaves the body, unless that leaves more limbs out (a gallop's skeleton)
    assign, costs = assignment(match_cost(template, tree, body, leaf_gcs, leaves, attach=False))
    cost = float(np.mean(costs)) if costs else float("inf")
    need = int(np.ceil(settings.min_matched * T))
    if len(assign) < max(need, 2) or cost > settings.max_match_cost:
        said = f"mean cost {cost:.2f}, at most {settings.max_match_cost}" if costs else "none near"
        raise DataError(f"does not match template {template.name} ({template.source}): "
                        f"{len(assign)} of {T} limbs matched, need {max(need, 2)}; {said}",
                        path=where, field="annotate.template",
                        fix="annotate this mesh with a template of its kind (or by hand), or "
                            "raise annotate.max_match_cost")
    attached = assignment(match_cost(template, tree, body, leaf_gcs, leaves))[0]
    if len(attached) >= len(assign):
        assign = attached
    # second pass: a limb posed far from the template's place (a head lowered to graze, legs
    # bunched in a gallop) takes a free end the first pass left, when the end is within the
    # limb's reach (match_cost with reach)
    left_gcs = [g for g in leaf_gcs if g not in assign]
    free = np.asarray([n for n in leaves if int(n) not in assign.values()], dtype=int)
    if left_gcs and len(free):
        C2 = match_cost(template, tree, body, left_gcs, free, reach=True)
        for r, c in zip(*linear_sum_assignment(C2)):
            if C2[r, c] < settings.missing_cost:
                assign[left_gcs[r]] = int(free[c])
    assign = _front_to_back(template, tree, body, assign)
    rp = template.gc(root_gc).place
    root_pos = body.to_world((np.asarray(rp["start"]) + np.asarray(rp["end"])) / 2.0)
    main_idx = np.flatnonzero(tree.main)
    root = int(main_idx[np.argmin(np.linalg.norm(tree.nodes[main_idx] - root_pos, axis=1))])
    dist, pred = dijkstra(tree.graph, indices=root, return_predecessors=True)
    pred = np.where(pred < 0, -1, pred)
    leaf_path = {g: _path(pred, n) for g, n in assign.items()}        # leaf ... root
    on_path = {g: set(p) for g, p in leaf_path.items()}

    def junction(names_in: set[str], path: list[int]) -> int:
        others = set().union(*[on_path[h] for h in assign if h not in names_in]) if \
            any(h not in names_in for h in assign) else {root}
        return next((n for n in path if n in others), root)

    paths: dict[str, list[int]] = {}
    top_node: dict[str, int] = {}  # where each matched GC's subtree meets the rest
    matched_leaves = {n: [x for x in below[n] if x in assign] for n in names}
    for g in template.gcs:
        ml = matched_leaves[g.name]
        if ml:
            top_node[g.name] = junction(set(below[g.name]), leaf_path[ml[0]])
    # a tip GC the skeleton has no free end for, whose side branches meet each other before
    # they meet the rest (a head without a snout end, both ears found): its path ends where
    # the farthest of them joins (one ear alone: its path is shared by the chain above it)
    ends_at = dict(assign)
    for g in leaf_gcs:
        side = [top_node[c] for c in kids[g] if c in top_node and top_node[c] != top_node.get(g)]
        if g not in assign and side:
            ends_at[g] = int(side[int(np.argmax(dist[side]))])
            leaf_path[g] = _path(pred, ends_at[g])
            matched_leaves[g] = [g] + matched_leaves[g]
    done, chained = set(), set()  # chained: GCs that start at a cut of their parent's path
    for leaf, node in ends_at.items():  # chains of template GCs above one matched leaf
        chain = [leaf]
        while template.gc(chain[-1]).parent is not None and \
                (ends[template.gc(chain[-1]).parent] == [chain[-1]] or
                 matched_leaves[template.gc(chain[-1]).parent] == [leaf]) and \
                template.gc(chain[-1]).parent != root_gc:
            chain.append(template.gc(chain[-1]).parent)
        p = leaf_path[leaf]
        j = top_node[chain[-1]]
        own = p[: p.index(j) + 1][::-1]                               # junction -> tip
        arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(tree.nodes[own], axis=0), axis=1))]
        chain = chain[::-1]                                           # top -> leaf
        lengths = [body.length(np.subtract(template.gc(c).place["end"],
                                           template.gc(c).place["start"]) / 1.0) for c in chain]
        cut = _split_by(arc, lengths) if len(own) > len(chain) else \
            list(np.linspace(0, len(own) - 1, len(chain) + 1).astype(int))
        cut = [cut[0]] + [_bend_near(tree.nodes[own], arc, c) for c in cut[1:-1]] + [cut[-1]]
        cut = _before_side_branches(np.asarray(own), arc, cut, tree.degree)
        for k, c in enumerate(chain):
            paths[c] = own[cut[k]: cut[k + 1] + 1]
            done.add(c)
            if k > 0:
                chained.add(c)
    for g in template.gcs:  # GCs above several matched leaves: between their children's junctions
        if g.name in done or not matched_leaves[g.name]:
            continue
        keys = {top_node[c] for c in kids[g.name] if c in top_node}
        if g.parent is not None and g.name in top_node:
            keys.add(top_node[g.name])
        keys = sorted(keys)
        best = (-1.0, [keys[0]])
        for a in keys:
            da, pa = dijkstra(tree.graph, indices=a, return_predecessors=True)
            for b in keys:
                if b != a and da[b] > best[0]:
                    best = (float(da[b]), _path(np.where(pa < 0, -1, pa), b)[::-1])
        paths[g.name] = _along_place(best[1], tree.nodes, body, g.place)
    labels = np.full(len(tree.nodes), -1)
    for name, p in paths.items():
        labels[p] = names.index(name)
    # a limb's first nodes inside its parent's body are the parent's (its root's surface); not
    # for a GC that continues its parent's path past a cut (a head on its neck: its skull is
    # thicker than its snout, and is the head's)
    for name, p in paths.items():
        par = template.gc(name).parent
        if par is None or par not in paths or len(p) < 4 or name in chained:
            continue
        R = tree.radius[p]
        k = int(np.argmax(R <= 1.25 * float(np.median(R[len(R) // 2:])))) // 2
        labels[p[:k]] = names.index(par)  # (the rest of the root, a hip, is the limb's)
        paths[name] = p[k:] if len(p) - k >= 2 else p
    src = np.flatnonzero(labels >= 0)
    _, _, source = dijkstra(tree.graph, indices=src, min_only=True, return_predecessors=True)
    fill = labels.copy()
    reach = source >= 0
    fill[reach] = labels[source[reach]]
    if (fill < 0).any():  # other pieces: the nearest labelled node in space
        near = cKDTree(tree.nodes[src]).query(tree.nodes[fill < 0], k=1)[1]
        fill[fill < 0] = labels[src[near]]
    missing = [n for n in names if n not in paths]
    return {k: np.asarray(v) for k, v in paths.items()}, fill, missing, cost


# ---- refinement ----------------------------------------------------------------------------
def refine(ctrls: list[np.ndarray], own: list[np.ndarray], radius0: list[np.ndarray],
           parents: list[int], partners: list[int], mirror: tuple[np.ndarray, np.ndarray],
           steps: int, seed: int = 0, max_own: int = 1500) -> list[np.ndarray]:
    """Control points (k_g, 3) of every GC optimised together (module docstring, step 5).

    own: each GC's surface samples (M_g, 3); radius0 (K_g,): initial mean radius per key (the
    keys evenly spaced in t); parents: the parent's index (-1: none); partners: the symmetric
    partner's index (-1); mirror: (point, unit normal) of the mid-plane."""
    if steps == 0 or not ctrls:
        return ctrls
    rng = np.random.default_rng(seed)
    dense = 32
    s = np.linspace(0.0, 1.0, dense)
    B = [torch.as_tensor(bernstein_basis(len(c) - 1, s)) for c in ctrls]
    X = [torch.tensor(c, dtype=torch.float64, requires_grad=True) for c in ctrls]
    X0 = [torch.tensor(c, dtype=torch.float64) for c in ctrls]
    logr = [torch.tensor(np.log(np.maximum(r, 1e-4)), dtype=torch.float64, requires_grad=True)
            for r in radius0]
    Q = [torch.as_tensor(o[rng.choice(len(o), min(len(o), max_own), replace=False)]
                         if len(o) else np.zeros((0, 3))) for o in own]
    scale = float(np.mean([np.exp(np.log(np.maximum(r, 1e-4))).mean() for r in radius0]))
    point, normal = (torch.as_tensor(v, dtype=torch.float64) for v in mirror)
    opt = torch.optim.Adam(X + logr, lr=0.2 * scale)
    for _ in range(steps):
        opt.zero_grad()
        curves = [b @ x for b, x in zip(B, X)]
        loss = torch.zeros((), dtype=torch.float64)
        for g, (C, q) in enumerate(zip(curves, Q)):
            if len(q) < 10:
                continue
            d2 = torch.cdist(q, C)
            t_idx = d2.argmin(1)
            inner = (t_idx > 0) & (t_idx < dense - 1)  # past an end: the cap's samples
            if inner.sum() < 5:
                continue
            d = d2[inner, t_idx[inner]]
            keys = torch.linspace(0, 1, len(logr[g]), dtype=torch.float64)
            t = torch.as_tensor(s, dtype=torch.float64)[t_idx[inner]]
            r = torch.exp(_lerp(keys, logr[g], t))
            loss = loss + ((d - r) ** 2).mean() / scale ** 2 + (torch.relu(d - r) ** 2).mean() / scale ** 2
        for g, p in enumerate(parents):
            if p >= 0:
                dmin = torch.linalg.norm(curves[p] - X[g][0], dim=1).min()
                loss = loss + torch.relu(dmin - 0.5 * torch.exp(logr[p]).mean()) ** 2 / scale ** 2
            if partners[g] > g:
                x = X[g]
                mirrored = x - 2.0 * ((x - point) @ normal)[:, None] * normal[None, :]
                mismatch = ((mirrored - X[partners[g]]) ** 2).sum(1).mean() / scale ** 2
                loss = loss + W_SYMMETRY * mismatch
                if len(logr[g]) == len(logr[partners[g]]):  # the same thickness profile
                    loss = loss + W_SYMMETRIC_RADII * ((logr[g] - logr[partners[g]]) ** 2).mean()
        for x, x0 in zip(X, X0):
            if len(x) > 2:
                loss = loss + 0.1 * ((x[2:] - 2 * x[1:-1] + x[:-2]) ** 2).sum() / scale ** 2
            loss = loss + 0.01 * ((x - x0) ** 2).sum() / scale ** 2
        loss.backward()
        opt.step()
    return [x.detach().numpy() for x in X]


def _lerp(keys: torch.Tensor, values: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
    """Piecewise-linear values (K,) at keys (K,) evaluated at t (M,)."""
    if len(keys) == 1:
        return values.expand(len(t))
    i = torch.clamp(torch.searchsorted(keys, t, right=True) - 1, 0, len(keys) - 2)
    w = (t - keys[i]) / (keys[i + 1] - keys[i])
    return values[i] * (1 - w) + values[i + 1] * w


# ---- the whole transfer --------------------------------------------------------------------
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


def _reach_back(poly: np.ndarray, to_body, start: np.ndarray, radius: float) -> np.ndarray:
    """A part on the root (a leg, the tail, the neck) as a rig has it: its skeleton path begins
    where it leaves the body's surface, a rig's limb at the joint inside (a hip above the
    thigh). The polyline (P, 3) is extended back along its own direction toward the template's
    `start` (body frame), at most START_REACH x its top `radius`."""
    tan = poly[min(8, len(poly) - 1)] - poly[0]
    tan /= max(float(np.linalg.norm(tan)), 1e-12)
    b0 = to_body(poly[0])
    back = to_body(poly[0] - tan) - b0                   # one world unit back, in body units
    length = float((start - b0) @ back / max(float(back @ back), 1e-12))
    length = min(max(length, 0.0), START_REACH * radius)
    if length <= 0.0:
        return poly
    return np.concatenate([np.linspace(poly[0] - length * tan, poly[0], 8)[:-1], poly])


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


def _curve_points(gc: GeneralizedCylinder, n: int = 64) -> np.ndarray:
    return np.asarray(gc.to_world(np.stack([np.linspace(-1, 1, n), np.zeros(n), np.zeros(n)], 1)))


def transfer_template(mesh: trimesh.Trimesh, template: Template,
                      settings: TransferSettings | None = None, where: str | None = None,
                      override: Orientation | None = None) -> Transfer:
    """The template's GCs on a (normalised) mesh (module docstring), in the mesh's coordinates;
    `rotation` turns them into the template's frame (``written``). override: the user's frame
    for this mesh (frame.read_override). DataError naming `where` when the mesh does not match
    the template in any orientation."""
    st = settings or TransferSettings()
    if not template.placed:
        lacking = [g.name for g in template.gcs if g.place is None][:3]
        raise DataError(f"template {template.name} does not say where its parts sit (no `place` "
                        f"for {lacking})", path=template.source, field="place",
                        fix="use a template exported from an annotated mesh (train.py "
                            "stage=annotate annotate.export_template=PATH), e.g. "
                            "datasets/animals/quadruped_transfer.yaml")
    V, F = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)
    rng = np.random.default_rng(st.seed)
    pts, _ = sample_surface(V, F, st.samples, rng)
    surface = np.concatenate([V, pts])
    proxy = closed_proxy(V, F, resolution=st.resolution, seed=st.seed)
    sk = proxy_skeleton(proxy, backend=st.skeleton)
    thick = np.maximum(local_thickness(sk.nodes, surface), proxy.h)  # (also for the retry)
    tree = skeleton_tree(sk, thick, st.min_branch_length, st.max_gcs)
    # orientation from the body's branches (curves of each branch of the main piece)
    branch_ids = np.unique(tree.branch_of[tree.main])
    curves = [tree.nodes[tree.branch_of == b] for b in branch_ids]
    volumes = [float(np.linalg.norm(np.diff(c, axis=0), axis=1).sum()) * tree.branch_r[b] ** 2
               for c, b in zip(curves, branch_ids)]
    up, front = parse_axis(st.up, "annotate.up"), parse_axis(st.front, "annotate.front")
    choice = choose(template, tree, surface, st, where, curves, volumes, up, front, override)
    orientation, body, found = choice.trial.orientation, choice.trial.body, choice.trial.found
    # the template's up vectors turned into this mesh's frame: written in the template's frame
    # (rotation R below) every mesh's are the template's own (one shape-latent layout)
    M = template_rotation(template, orientation)

    def attempt(on: Tree, frame: BodyFrame):
        """correspond's match, or the DataError that refuses it."""
        try:
            return correspond(template, on, frame, st, where)
        except DataError as e:
            return e

    paths, labels, missing, cost = found
    if missing:  # a stubby part (a short tail) pruned with the spurs: once more with finer ones
        fine = skeleton_tree(sk, thick, FINER * st.min_branch_length, st.max_gcs)
        again = attempt(fine, body)
        if not isinstance(again, DataError) and len(again[2]) < len(missing):
            tree, (paths, labels, missing, cost) = fine, again
    owner = labels[cKDTree(tree.nodes).query(surface, k=1)[1]]
    names = template.names
    floor = 1e-3 * float(np.ptp(surface, axis=0).max())
    gcs: dict[str, GeneralizedCylinder] = {}
    for g, tgc in enumerate(template.gcs):
        if tgc.name not in paths:
            continue
        own = surface[owner == g]
        poly = chain_polyline(tree.nodes[paths[tgc.name]], own, tgc.extend)
        up = _safe_up(M @ np.asarray(tgc.up), poly[-1] - poly[0])
        gcs[tgc.name] = template_gc(dataclasses.replace(tgc, up=tuple(up)), poly, own, st.margin,
                                    floor, where)
    # refinement of every matched GC's curve together
    matched = [n for n in names if n in gcs]
    parent_ix = [matched.index(template.gc(n).parent) if template.gc(n).parent in matched else -1
                 for n in matched]
    partner_ix = [matched.index(template.gc(n).symmetric) if template.gc(n).symmetric in matched
                  else -1 for n in matched]
    mid = body.to_world(np.zeros(3))
    ctrls = [np.asarray(gcs[n].to_dict()["curve"]["points"], dtype=np.float64) for n in matched]
    r0 = [np.array([np.sqrt(np.prod(k["radii"])) for k in gcs[n].to_dict()["keys"]]) / (1 + st.margin)
          for n in matched]
    own_of = [surface[owner == names.index(n)] for n in matched]
    ctrls = refine(ctrls, own_of, r0, parent_ix, partner_ix, (mid, orientation.left),
                   st.refine_steps, st.seed)
    dense_s = np.linspace(0.0, 1.0, 64)
    root_name = next(n for n in names if template.gc(n).parent is None)
    for n, c, own, r in zip(matched, ctrls, own_of, r0):
        tgc = template.gc(n)
        poly = bernstein_basis(len(c) - 1, dense_s) @ c
        if tgc.parent == root_name:
            poly = _reach_back(poly, body.to_body, np.asarray(tgc.place["start"]), float(r[0]))
        up = _safe_up(M @ np.asarray(tgc.up), poly[-1] - poly[0])
        gcs[n] = template_gc(dataclasses.replace(tgc, up=tuple(up)), poly, own, st.margin, floor,
                             where)
        if any(k in tgc.place for k in AT_KEYS):  # the annotator's ends
            poly = _moved_ends(gcs[n], tgc.place)
            up = _safe_up(M @ np.asarray(tgc.up), poly[-1] - poly[0])
            gcs[n] = template_gc(dataclasses.replace(tgc, up=tuple(up)), poly, own, st.margin,
                                 floor, where)
    surface_body = body.to_body(surface) if missing else None
    for n in missing:  # a GC from where the part would attach to the surface where it would end
        tgc = template.gc(n)
        pl = tgc.place
        start = body.to_world(np.asarray(pl["start"]))
        vec = (np.asarray(pl["end"]) - np.asarray(pl["start"])) * body.half @ body.R
        length = max(float(np.linalg.norm(vec)), floor)
        p = tgc.parent
        while p is not None and p not in gcs:
            p = template.gc(p).parent
        if p is not None:
            C = _curve_points(gcs[p])
            start = C[np.argmin(np.linalg.norm(C - start, axis=1))]
        # the part's stub (a short tail the skeleton pruned) is the surface nearest its place's
        # end: the GC reaches it, within the part's length (else the template's direction)
        off = (surface_body - np.asarray(pl["end"])) / MISSING_SIGMA
        tip = surface[np.argmin(np.linalg.norm(off, axis=1))]
        reach = float(np.linalg.norm(tip - start))
        stub = floor < reach <= MISSING_REACH * length
        if stub:
            vec, length = tip - start, reach * (1.0 + MISSING_PAST)
        else:
            length = 0.25 * length
        r = max(pl["radius"] * body.half[0] * 0.5, floor)
        gcs[n] = _straight(tgc, start, vec / np.linalg.norm(vec), length, r,
                           M @ np.asarray(tgc.up))
        if stub:  # grown over the surface around its tip (the stub itself)
            near = surface[np.linalg.norm(surface - tip, axis=1) <= 3.0 * r]
            gcs[n] = grow_to_cover([gcs[n]], near)[0]
    ordered = [gcs[n] for n in names]
    for g, n in enumerate(names):  # alone first: a GC holds its own samples near it
        own = surface[owner == g]
        if n in missing or not len(own):
            continue
        rho, _ = rho_matrix([ordered[g]], own)
        ordered[g] = grow_to_cover([ordered[g]], own[rho[0] <= OWN_REACH])[0]
    ordered = grow_to_cover(ordered, surface)
    root = next(n for n in names if template.gc(n).parent is None)
    if root in paths:  # the template's parts are tubes: a plate (a chair's seat) is no torso
        keys = ordered[names.index(root)].to_dict()["keys"]
        r_gc = float(np.median([np.sqrt(np.prod(k["radii"])) for k in keys]))
        tube = float(tree.radius[paths[root]].max()) / max(r_gc, 1e-12)
        if tube < st.min_tube:
            raise DataError(f"does not match template {template.name} ({template.source}): its "
                            f"{root} is no tube (inside it at most {tube:.2f} of the {root} GC's "
                            f"radius thick, need {st.min_tube}: a plate or a frame, a chair's seat)",
                            path=where, field="annotate.template",
                            fix="annotate this mesh with a template of its kind (or by hand), or "
                                "lower annotate.min_tube")
    pp, _, _ = gc_membership(surface, ordered)
    coverage = float((np.bincount(pp, minlength=len(surface)) > 0).mean())
    return Transfer(gcs=ordered, matched=matched, missing=missing, cost=cost,
                    orientation=orientation, coverage=coverage,
                    rotation=to_template(orientation, Orientation(template.up, template.front)),
                    confidence=choice.confidence, warnings=choice.warnings,
                    source="override" if override is not None else
                    "given" if "given" in orientation.source else "detected")


# ---- templates from annotated meshes -------------------------------------------------------
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
