"""Correspondence: the template's limbs onto the skeleton tree's free ends, and each matched
GC's path (docs/transfer.md, "How a template is placed", step 2)."""
from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from ngc_gen.data.autogc.template import Template
from ngc_gen.data.errors import DataError

from .chain_joints import joint_near
from .leg_order import LEG_DOWN, _legs_by_start
from .side_pairs import paired_junction
from .transfer_settings import TransferSettings
from .tree import BodyFrame, Tree

SIGMA_TIP = 0.3    # tip position error (body units) that costs 1
W_DIRECTION = 1.0  # weight of 1 - cos(direction toward the tip)
SIGMA_ATTACH = 0.3  # error (body units, front to back) of where a limb's branch leaves the body
W_ATTACH = 1.0     # weight of that attachment term
MAX_ATTACH = 3.0   # at most this much: a galloping animal's skeleton may join its legs mid-body
W_THICKNESS = 0.5  # weight of log(thickness ratio)^2
BEYOND = 1e3       # the cost of a free end above where a leg attaches (second pass)
REACH_OUT = 0.2    # a limb whose chain ends this much further front (back) than it starts is an
                   # end's (a head, a tail): its free end lies beyond where the chain starts
SIDE_SLACK = 0.05  # a left limb's free end lies at most this far (body units) right of the middle
MID_SLACK = 0.15   # a short tail's end lies at most this x the body's thickest radius off the
                   # mid-plane (standing animals' tails: 0.00-0.09; spurs in one hip: 0.23, 0.37)
END_REACH = 1.5    # a chain's path passing this x SIGMA_TIP from where its template part ends
                   # ends the template's part there (_template_end)
W_SHORT = 1.0      # second pass, a part on the mid-plane: weight of log(branch length / the
                   # GC's template length)^2 for a shorter branch: a spur inside the hip, within
                   # a tail's reach, is no tail (a leg's branch may end where a bunched leg joins)


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
    root = template.root
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
    long = branch_lengths(tree)[tree.branch_of[leaves]] if reach else None
    at_front = body.to_body(tree.branch_root[tree.branch_of[leaves]])[:, 0]  # (L,)
    C = np.zeros((len(leaf_gcs), len(leaves)))
    for i, name in enumerate(leaf_gcs):
        pl = template.gc(name).place
        end, start = np.asarray(pl["end"]), np.asarray(pl["start"])
        d_t = end - start
        d_t /= max(np.linalg.norm(d_t), 1e-12)
        sigma = np.full(3, SIGMA_TIP)
        chain = _chain(template, name)
        if template.gc(name).symmetric is None and len(chain) > 1:
            # on the mid-plane at a chain's end (a head on its neck): it turns aside at the
            # chain's joints, its side hardly tells; a part straight on the root (a tail)
            # leaves the body on the mid-plane, where a spur out of one hip does not lie
            sigma[1] *= 2.0
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
            # and a limb that reaches down (a leg) ends below where it attaches, an end's (a
            # head, a tail) beyond it (_behind): its reach also holds an ear above the shoulder
            # or beside a short neck (a grazing head may point anywhere in front)
            start_z = template.gc(top).place["start"][2]
            up = tip[:, 2] >= start_z if start_z - end[2] >= LEG_DOWN else np.zeros(len(tip), bool)
            away = up | _behind(template, top, end, tip)
            pos = ((at - length) / SIGMA_TIP) ** 2 + side + np.where(away, BEYOND, 0.0)
        else:
            pos = (((tip - end) / sigma) ** 2).sum(1)
        short = np.minimum(np.log(np.maximum(long, 1e-9) / max(body.length(end - start), 1e-9)),
                           0.0) if reach and template.gc(name).symmetric is None else 0.0
        C[i] = (pos + W_ATTACH * att + W_DIRECTION * (1.0 - d_mesh @ d_t)
                + W_THICKNESS * np.log(np.maximum(r_mesh, 1e-6) / (pl["radius"] / r_root)) ** 2
                + W_SHORT * short ** 2)
    return C


def _behind(template: Template, top: str, end: np.ndarray, tip: np.ndarray) -> np.ndarray:
    """(L,) whether each free end (body frame) lies on the near side of where an end's chain
    (a neck and head, a tail: REACH_OUT front or back) starts: within the chain's reach, an ear
    beside a short-necked head (an elephant's, beside its trunk) or a spur inside the hip is
    still no head or tail, whose free ends lie beyond the chain's start, as a leg's lie below."""
    start_x = float(template.gc(top).place["start"][0])
    out = float(end[0]) - start_x
    if abs(out) < REACH_OUT:
        return np.zeros(len(tip), bool)
    return (tip[:, 0] - start_x) * np.sign(out) <= 0.0


def branch_lengths(tree: Tree) -> np.ndarray:
    """(B,) arc length of each branch of the tree (its edges within the branch)."""
    G = tree.graph.tocoo()
    same = tree.branch_of[G.row] == tree.branch_of[G.col]
    return np.bincount(tree.branch_of[G.row[same]], weights=G.data[same],
                       minlength=len(tree.branch_r)) / 2.0


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


def _template_end(path: list[int], nodes: np.ndarray, body: BodyFrame, place: dict) -> int:
    """The index on a chain's path (junction -> tip) where the template's chain ends: the node
    nearest its last GC's place end when within END_REACH x SIGMA_TIP of it (body units, twice
    that across) and the tip is not (the path runs on away from there), else the tip. What runs
    on past it (an elephant's trunk) is the last GC's, and the chain is cut by the template's
    lengths up to there only."""
    off = body.to_body(nodes[path]) - np.asarray(place["end"])
    d = np.linalg.norm(off / (SIGMA_TIP * np.array([1.0, 2.0, 1.0])), axis=1)
    k = int(np.argmin(d))
    return k if d[k] <= END_REACH < d[-1] and k > 0 else len(path) - 1


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


def _assign(template: Template, tree: Tree, body: BodyFrame, settings: TransferSettings,
            where, leaf_gcs: list[str], leaves: np.ndarray) -> tuple[dict[str, int], float]:
    """{template tip GC: tree leaf} by one optimal assignment, a second pass for the limbs left
    out and the front-to-back swap, and the mean match cost; DataError when the mesh does not
    match (too few limbs, too costly)."""
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
    assign = _on_mid_plane(template, tree, body, _on_sides(template, tree, body, assign))
    if len(assign) < max(need, 2):
        raise DataError(f"does not match template {template.name} ({template.source}): "
                        f"{len(assign)} of {T} limbs matched on their own sides, need "
                        f"{max(need, 2)}", path=where, field="annotate.template",
                        fix="annotate this mesh with a template of its kind (or by hand), or "
                            "give its frame (frame: {up: +y, front: -z} in its YAML)")
    return _front_to_back(template, tree, body, assign), cost


def _on_sides(template: Template, tree: Tree, body: BodyFrame,
              assign: dict[str, int]) -> dict[str, int]:
    """The assignment without the limbs of a symmetric pair whose free end lies more than
    SIDE_SLACK (body units) across the mid-plane from the side the template puts them on (a
    spur under the right shoulder taken for the left leg when the legs' ends are not free):
    such a limb is missing, and stands in on its own side, rather than named on the other."""
    out = dict(assign)
    for n, leaf in assign.items():
        side = float(template.gc(n).place["end"][1])
        if template.gc(n).symmetric is not None and abs(side) >= SIDE_SLACK and \
                body.to_body(tree.nodes[leaf])[1] * np.sign(side) < -SIDE_SLACK:
            del out[n]
    return out


def _on_mid_plane(template: Template, tree: Tree, body: BodyFrame,
                  assign: dict[str, int]) -> dict[str, int]:
    """The assignment without a part on the mid-plane straight on the root (a tail) whose free
    end lies MID_SLACK x the body's thickest radius off the mid-plane on a branch shorter than
    its template part: a tail leaves the body on the mid-plane and hangs there or swings aside
    at full length (a posed horse's), a short spur out of one hip (the skeleton joined the tail
    to the hind legs) ends in that hip's flank. Missing (a stand-in), not named on the hip."""
    out = dict(assign)
    root = template.root
    thick = float(tree.radius[tree.main].max())
    long = branch_lengths(tree)
    for n, leaf in assign.items():
        g = template.gc(n)
        if g.symmetric is None and g.parent == root and abs(float(g.place["end"][1])) < SIDE_SLACK \
                and abs(body.to_body(tree.nodes[leaf])[1]) * body.half[1] > MID_SLACK * thick \
                and long[tree.branch_of[leaf]] < body.length(np.subtract(g.place["end"],
                                                                         g.place["start"])):
            del out[n]
    return out


def correspond(template: Template, tree: Tree, body: BodyFrame, settings: TransferSettings,
               where: str | None = None) -> tuple[dict[str, np.ndarray], np.ndarray, list[str], float]:
    """Paths (node indices, root side first) of the matched template GCs, the template GC index
    of every tree node (N,), the missing GC names and the mean match cost. DataError (one line)
    when the mesh does not match the template."""
    leaf_gcs = _tips(template)[0]
    leaves = np.flatnonzero(tree.main & (tree.degree == 1))
    if len(leaves) < 2:
        raise DataError(f"its skeleton has {len(leaves)} free ends, nothing to put template "
                        f"{template.name}'s ({template.source}) {len(leaf_gcs)} limbs on",
                        path=where, field="mesh",
                        fix="give this mesh its own annotation, or use a template of its kind")
    assign, cost = _assign(template, tree, body, settings, where, leaf_gcs, leaves)
    paths, chained = _paths(template, tree, body, assign)
    by_start = _legs_by_start(template, body.to_body(tree.nodes), assign, paths)  # (leg_order)
    if by_start != assign:
        assign = by_start
        paths, chained = _paths(template, tree, body, assign)
    labels = _labels(template, tree, paths, chained)
    missing = [n for n in template.names if n not in paths]
    return {k: np.asarray(v) for k, v in paths.items()}, labels, missing, cost


def _chain_cuts(template: Template, tree: Tree, body: BodyFrame, own: list[int],
                chain: list[str]) -> list[int]:
    """Where a chain of template GCs (top -> leaf) cuts its path `own` (junction -> tip): by
    the template's lengths up to where the template's chain ends (``_template_end``), each
    inner cut moved to a waist or bend near it (``chain_joints``) and before side branches;
    on the mid-plane, the last GC (a head) started where a mirrored pair of side branches
    leaves the path (``side_pairs``)."""
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(tree.nodes[own], axis=0), axis=1))]
    lengths = [body.length(np.subtract(template.gc(c).place["end"],
                                       template.gc(c).place["start"]) / 1.0) for c in chain]
    k = _template_end(own, tree.nodes, body, template.gc(chain[-1]).place) \
        if len(chain) > 1 else len(own) - 1
    cut = _split_by(arc[: k + 1], lengths)[:-1] + [len(own) - 1] if k + 1 > len(chain) else \
        list(np.linspace(0, len(own) - 1, len(chain) + 1).astype(int))
    cut = [cut[0]] + [joint_near(tree.nodes[own], tree.radius[own], arc, c, k)
                      for c in cut[1:-1]] + [cut[-1]]
    cut = _before_side_branches(np.asarray(own), arc, cut, tree.degree)
    if len(chain) > 1 and all(template.gc(c).symmetric is None for c in chain):
        # a chain on the mid-plane: its free end's part (a head on its neck) starts at the
        # first mirrored pair of side branches (ears, horns) in front of the chain's start
        j = paired_junction(tree, body, own, lambda tips: ~_behind(
            template, chain[0], np.asarray(template.gc(chain[-1]).place["end"]), tips))
        if j is not None:
            cut[-2] = int(np.clip(j - 1, cut[-3] + 1, cut[-1] - 1))
    return cut


def _paths(template: Template, tree: Tree, body: BodyFrame,
           assign: dict[str, int]) -> tuple[dict[str, list[int]], set[str]]:
    """Each matched GC's path (node indices, root side first): chains above one matched leaf
    share its path by the template's lengths, a GC above several runs between its children's
    junctions (module docstring); and the GCs that start at a cut of their parent's path."""
    kids = _children(template)
    leaf_gcs, below, ends = _tips(template)
    names = template.names
    root_gc = template.root
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
        chain = chain[::-1]                                           # top -> leaf
        cut = _chain_cuts(template, tree, body, own, chain)
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
    return paths, chained


def _labels(template: Template, tree: Tree, paths: dict, chained: set[str]) -> np.ndarray:
    """The template GC index of every tree node: its path's, a limb's first nodes inside its
    parent the parent's (the limb's path trimmed there), every other node the nearest labelled
    one's along the tree (ears, antlers), other pieces the nearest in space."""
    names = template.names
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
    return fill
