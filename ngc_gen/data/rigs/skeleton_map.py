"""A skeleton's joints onto the quadruped template's GCs by the skeleton's own structure and
geometry, without a joint map written by hand.

At the rest pose, over the joints that move skin (a joint whose subtree carries no skin weight
is not part of the body; a second root, an IK foot or a detached leg, is hung from the nearest
joint of the main tree):
- legs: the chains whose ends reach the ground (within GROUND x the mesh's height of its lowest
  point; the four lowest when more do: a trunk or a tail can hang there too); fewer than four
  and the skeleton is refused. A leg is its path from where it leaves the others (its deepest
  ancestor shared with another foot) to the foot; its leading joints whose bone runs more
  across the body than down, or that sit nearer the mid-plane than MIDLINE x its foot, are its
  root inside the body: skinned to the leg, not on its curve;
- the body frame: up (given, or the axis along which four feet lie lowest), front along the
  line from one pair of feet to the other, left = up x front;
- the joints left over hang off the body in pieces; the pieces that reach past the front or the
  back legs' tops sit at an end. The end whose biggest piece carries more skin is the front:
  that piece is neck + head. Along its main path (into the child with the most skin below it
  each time; a side branch, ears or horns, goes with the main-path joint nearest to where it
  starts) the head is the deepest joint past the front legs' tops that, with what follows it,
  carries HEAD_SHARE of the piece's skin (a jaw or a trunk carries less); its joints behind
  the front legs' tops are the torso's. The piece that reaches farthest past the other end is
  the tail; the leading joints of its main path not past the back legs' tops sit in the hips
  (a pelvis the tail hangs from moves the rump and whatever covers it: armour, a saddle
  cloth) and are the torso's, as is a first joint that sits on the spine, and so are the
  leading joints past them whose skin spans more than WIDE of the body's width at the back
  legs' tops (a spine end past the hips that moves the top of the rump: a tail is far
  narrower than the body it leaves). The spine from the
  back legs' branch to the front legs', with what the neck and the tail gave it, less an end
  joint that carries no skin (a root on the ground the legs hang from), is the torso's curve;
  every other joint is skinned to the torso.

A per-skeleton map file (`load_joint_map`) is the fallback a user writes where this is wrong.
Template GCs are found by their names (torso, neck, head, tail, leg_fl, leg_fr, leg_bl, leg_br;
carved GCs need no joints).
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from ngc_gen.data.autogc.template import Template
from ngc_gen.data.errors import DataError

from .rig import Rig

ROLES = ("torso", "neck", "head", "tail", "leg_fl", "leg_fr", "leg_bl", "leg_br")
GROUND = 0.1    # a foot ends within this share of the mesh's height of its lowest point
MIDLINE = 0.5   # leading leg joints nearer the mid-plane than this x their foot sit in the body
HEAD_SHARE = 0.5  # the head and what follows it carry this share of the neck + head's skin
SAME = 0.01     # joints nearer than this x the skeleton's size sit at the same place
WIDE = 2 / 3    # a tail joint whose skin spans this share of the body's width moves the rump
SECTION = 0.05  # the body's section at the back legs' tops: within this x its size
AXES = np.vstack([np.eye(3), -np.eye(3)])


@dataclass
class JointMap:
    """Per template GC {chain: [joint index], skinned: [joint index]} (indices into the rig's
    joints, as `Template.resolve_joints` gives them) and the rig's body frame (unit vectors)."""

    resolved: dict[str, dict[str, list[int]]]
    up: np.ndarray
    front: np.ndarray
    source: str = "structure"

    @property
    def left(self) -> np.ndarray:
        return np.cross(self.up, self.front)

    def for_template(self, template: Template, rig: Rig) -> "JointMap":
        """This map keyed by `template`'s GCs (carved ones need no joints); a refusal naming
        the GC when a chain GC of the template is not in it."""
        out = {}
        for g in template.gcs:
            if g.carve is None and g.name not in self.resolved:
                raise _refuse(rig, f"the joint map ({self.source}) has no GC {g.name!r}")
            out[g.name] = self.resolved.get(g.name, {"chain": [], "skinned": []})
        return JointMap(out, self.up, self.front, self.source)

    def names(self, rig: Rig) -> dict:
        """The map as a map file holds it: {gc: {joints: [...], skinned: [...]}, frame: ...}."""
        jn = rig.joint_names
        out = {g: {"joints": [jn[j] for j in r["chain"]], "skinned": [jn[j] for j in r["skinned"]]}
               for g, r in self.resolved.items() if r["chain"]}
        out["frame"] = {"up": [round(float(x), 4) for x in self.up],
                        "front": [round(float(x), 4) for x in self.front]}
        return out


def _refuse(rig: Rig, what: str) -> DataError:
    return DataError(f"cannot map the skeleton onto the quadruped template: {what}",
                     path=rig.source, field="joints",
                     fix="write a joint map file (template GC -> bone names, docs/zeroad.md)")


def _graph(rig: Rig) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(rest joint positions (J, 3), parent (J,) over the skinned joints with second roots hung
    from the nearest joint of the main tree, skinned mask (J,), skin load (J,))."""
    P = rig.joint_positions()
    par = rig.joint_parent()
    J = len(par)
    load = np.bincount(rig.skin_joints.ravel(), rig.skin_weights.ravel(), minlength=J)[:J]
    sub = load.copy()
    order = np.argsort(_depth(par))[::-1]
    for j in order:  # children before parents: subtree loads
        if par[j] >= 0:
            sub[par[j]] += sub[j]
    active = sub > 1e-6
    roots = [j for j in range(J) if active[j] and (par[j] < 0 or not active[par[j]])]
    if not roots:
        raise _refuse(rig, "no joint carries skin weight")
    size = {r: sub[_subtree(par, r)].sum() for r in roots}
    main = max(roots, key=size.get)
    par = par.copy()
    in_main = np.zeros(J, bool)
    in_main[_subtree(par, main)] = True
    in_main &= active
    cand = np.flatnonzero(in_main)  # hung from the main tree only, never from one another
    for r in roots:
        if r != main:
            par[r] = cand[np.argmin(np.linalg.norm(P[cand] - P[r], axis=1))]
    par[main] = -1
    return P, np.where(active, par, -1), active, load


def _depth(par: np.ndarray) -> np.ndarray:
    depth = np.zeros(len(par), np.int64)
    for j in range(len(par)):
        p = par[j]
        while p >= 0 and depth[j] <= len(par):
            depth[j] += 1
            p = par[p]
    return depth


def _subtree(par: np.ndarray, root: int) -> list[int]:
    out, stack = [], [root]
    kids = {}
    for j, p in enumerate(par):
        kids.setdefault(int(p), []).append(j)
    while stack:
        j = stack.pop()
        out.append(j)
        stack.extend(kids.get(j, []))
    return out


def _path_up(par: np.ndarray, j: int) -> list[int]:
    """j, its parent, ... the root."""
    out = [j]
    while par[out[-1]] >= 0:
        out.append(int(par[out[-1]]))
    return out


def _feet(P, par, active, V, up) -> list[int]:
    """The skinned leaves within GROUND x height of the mesh's lowest point along `up` (the
    four lowest of them when more reach: a trunk or a tail can hang near the ground too)."""
    h, hv = P @ up, V @ up
    kids = np.bincount(par[par >= 0], minlength=len(par))
    leaves = np.flatnonzero(active & (kids == 0))
    near = sorted((float(h[j]), int(j)) for j in leaves if h[j] - hv.min() <= GROUND * np.ptp(hv))
    return sorted(j for _, j in near[:4])


def _detect_up(P, par, active, V) -> np.ndarray:
    """The axis direction along which four feet reach the ground, the one whose fifth lowest
    leaf stands farthest above them (ValueError when none has four)."""
    best, score = None, -np.inf
    kids = np.bincount(par[par >= 0], minlength=len(par))
    leaves = np.flatnonzero(active & (kids == 0))
    for a in AXES:
        if len(_feet(P, par, active, V, a)) != 4:
            continue
        h = np.sort(P[leaves] @ a - (V @ a).min()) / np.ptp(V @ a)
        s = h[4] - h[3] if len(h) > 4 else 1.0
        if s > score:
            best, score = a, s
    if best is None:
        raise ValueError("no axis has four chains reaching the ground")
    return best


@dataclass
class _Legs:
    chains: list[list[int]]   # per leg, body end first
    roots: list[list[int]]    # per leg, the joints inside the body (skinned, not on the curve)
    branch: list[int]         # per leg, where it leaves the others
    feet: list[int]


def _legs(P, par, feet, up, axis) -> _Legs:
    """Each foot's leg (module docstring): its joints from where it leaves the other feet's
    paths; the leading ones whose bone runs more sideways than down, or that sit nearer the
    mid-plane (across `axis`) than MIDLINE x the foot, are its root inside the body."""
    paths = [_path_up(par, f) for f in feet]
    sets = [set(p) for p in paths]
    across = np.cross(up, axis)
    chains, roots, branch = [], [], []
    for i, p in enumerate(paths):
        shared = set().union(*(sets[k] for k in range(len(feet)) if k != i))
        b = next(j for j in p if j in shared)
        leg = p[: p.index(b)][::-1]  # body end first
        off = np.abs((P[leg] - P[b]) @ across)
        k = 0
        while k < len(leg) - 1:
            d = P[leg[k + 1]] - P[leg[k]]
            down = -(d @ up)
            side = abs(d @ across)
            if down > side and off[k] >= MIDLINE * off[-1]:
                break
            k += 1
        chains.append(leg[k:])
        roots.append(leg[:k])
        branch.append(b)
    return _Legs(chains, roots, branch, list(feet))


def _frame(P, feet, up) -> tuple[np.ndarray, list[int], list[int]]:
    """(axis (3,), pair A, pair B): the feet (indices into `feet`) split into two pairs along
    the body's long axis (the feet's main horizontal direction), axis from pair A toward pair
    B (which is the front is not known yet)."""
    F = P[feet] - (P[feet] @ up)[:, None] * up
    c = F - F.mean(0)
    axis = np.linalg.svd(c, full_matrices=False)[2][0]
    axis -= (axis @ up) * up
    axis /= np.linalg.norm(axis)
    order = np.argsort(c @ axis)
    return axis, [int(i) for i in order[:2]], [int(i) for i in order[2:]]


def _pieces(par, active, taken: set[int]) -> list[list[int]]:
    """The skinned joints not in `taken`, split into the subtrees they form (parents first)."""
    free = [j for j in range(len(par)) if active[j] and j not in taken]
    free_set = set(free)
    tops = [j for j in free if par[j] < 0 or par[j] not in free_set]
    kids: dict[int, list[int]] = {}
    for j in free:
        kids.setdefault(int(par[j]), []).append(j)
    out = []
    for t in tops:  # through free joints only
        piece, stack = [], [t]
        while stack:
            j = stack.pop()
            piece.append(j)
            stack.extend(reversed(kids.get(j, [])))
        out.append(piece)
    return out


def _tree_path(par, a: int, b: int) -> list[int]:
    """Joints on the tree path from a to b."""
    pa, pb = _path_up(par, a), _path_up(par, b)
    common = next(j for j in pa if j in set(pb))
    return pa[: pa.index(common) + 1] + pb[: pb.index(common)][::-1]


def _main_path(par, piece: list[int], load: np.ndarray) -> list[int]:
    """From the piece's first joint, each time into the child whose subtree carries the most
    skin, to a leaf."""
    kids: dict[int, list[int]] = {}
    inside = set(piece)
    for j in piece:
        if par[j] in inside:
            kids.setdefault(int(par[j]), []).append(j)
    sub = {j: float(load[j]) for j in piece}
    for j in reversed(piece):  # pieces list parents first
        if par[j] in inside:
            sub[int(par[j])] += sub[j]
    path = [piece[0]]
    while kids.get(path[-1]):
        path.append(max(kids[path[-1]], key=sub.get))
    return path


def _neck_head(par, piece, P, load, axis, top):
    """(neck skinned, head skinned, its main path's joints behind the front legs' tops (on the
    torso's curve; they and their side branches are skinned to the torso), neck chain, head
    joint) of the piece at the front. A side branch goes with the main-path joint nearest to
    where it starts (ears hung from the last neck joint are the head's); the head is the
    deepest joint past `top` that, with what follows it, carries HEAD_SHARE of the piece's
    skin (a jaw or a trunk carries less)."""
    path = _main_path(par, piece, load)
    k = 0
    while k < len(path) - 1 and float(P[path[k]] @ axis) <= top:
        k += 1
    at = {j: i for i, j in enumerate(path)}
    members = set(piece)
    for j in piece:
        if j not in at and par[j] in at and j in members:  # a side branch: all of its subtree
            near = int(np.argmin(np.linalg.norm(P[path] - P[j], axis=1)))
            for t in _subtree(par, j):
                if t in members:
                    at[t] = near
    group = np.zeros(len(path))
    np.add.at(group, [at[j] for j in piece], load[piece])
    after = np.cumsum(group[::-1])[::-1]  # skin of joint i and all that follows it
    h = max((i for i in range(k, len(path)) if after[i] >= HEAD_SHARE * after[0]), default=k)
    head = path[h]
    neck_chain = path[k: h + 1]
    if len(neck_chain) < 2:
        attach = int(par[path[k]])
        neck_chain = ([attach] if attach >= 0 else []) + neck_chain
    neck = [j for j in piece if k <= at[j] < h]
    head_skin = [j for j in piece if at[j] >= h]
    return neck, head_skin, path[:k], neck_chain, head


def _spans_body(across: np.ndarray, owner: np.ndarray, j: int, section: float) -> bool:
    """Whether the vertices whose skin joint j holds most of (`owner`: per vertex, its joint)
    span more than WIDE of `section` (the body's width) in `across` (per vertex, its position
    across the body)."""
    own = across[owner == j]
    return len(own) > 1 and float(np.ptp(own)) > WIDE * section


def _tail(par, piece, P, load, axis, top, size, rig, up):
    """(tail chain, tail skinned, its main path's joints that are the torso's) of the piece at
    the back. Its leading joints not past the back legs' tops `top` along `axis` sit inside
    the body at the hips (a pelvis the tail hangs from): they move the rump (and what covers
    it: armour, a saddle cloth); so do the next ones whose skin spans the body's width there
    (`_spans_body`). They and their side branches are the torso's, on its curve; a first
    tail joint that sits on its parent is skinned to the torso too."""
    path = _main_path(par, piece, load)
    k = 0
    while k < len(path) - 1 and float(P[path[k]] @ axis) >= top:
        k += 1
    V = rig.posed()
    across, owner = V @ np.cross(up, axis), rig.dominant_joint()
    band = np.abs(V @ axis - top) <= SECTION * size
    section = float(np.ptp(across[band])) if band.sum() > 1 else 0.0
    while k < len(path) - 2 and section > 0 and _spans_body(across, owner, path[k], section):
        k += 1
    chain = path[k:]
    skin = [j for j in _subtree(par, path[k]) if j in set(piece)]
    if np.linalg.norm(P[path[k]] - P[par[path[k]]]) < SAME * size and len(skin) > 1:
        skin = skin[1:]  # it sits on the spine: it moves the rump
    return chain, skin, path[:k]


def structure_map(rig: Rig, template: Template | None = None, up=None) -> JointMap:
    """The joint map of `rig` onto `template` (None: the ROLES alone) by its structure (module
    docstring); `up`: the rig's up axis (3,) when known. DataError with one line when it
    cannot be mapped."""
    missing = [r for r in ROLES if template is not None and r not in template.names]
    extra = [] if template is None else \
        [g.name for g in template.gcs if g.name not in ROLES and g.carve is None]
    if missing or extra:
        raise _refuse(rig, f"the template's GCs {extra or missing} are not the quadruped's "
                           f"{', '.join(ROLES)}")
    P, par, active, load = _graph(rig)
    V = rig.posed()
    if up is None:
        try:
            up = _detect_up(P, par, active, V)
        except ValueError as e:
            raise _refuse(rig, str(e)) from None
    up = np.asarray(up, np.float64) / np.linalg.norm(up)
    feet = _feet(P, par, active, V, up)
    if len(feet) != 4:
        raise _refuse(rig, f"{len(feet)} chains reach the ground, a quadruped has 4")
    axis, pair_a, pair_b = _frame(P, feet, up)
    legs = _legs(P, par, feet, up, axis)
    size = float(np.ptp(V, axis=0).max())
    return _assemble(rig, template, P, par, active, load, up, axis, legs, (pair_a, pair_b), size)


def _ends(P, par, active, load, legs, pairs, axis, spine):
    """(pieces at end A, pieces at end B, other pieces, the legs' tops along axis per end)."""
    taken = set(spine)
    for c, r in zip(legs.chains, legs.roots):
        taken.update(c + r)
    tops = [min(float(P[legs.chains[i][0]] @ axis) for i in pairs[0]),
            max(float(P[legs.chains[i][0]] @ axis) for i in pairs[1])]
    at_a, at_b, rest = [], [], []
    for piece in _pieces(par, active, taken):
        a = P[piece] @ axis
        past_a, past_b = tops[0] - a.min(), a.max() - tops[1]
        if max(past_a, past_b) <= 0:
            rest.append(piece)
        else:
            (at_a if past_a > past_b else at_b).append(piece)
    return at_a, at_b, rest, tops


def _assemble(rig, template, P, par, active, load, up, axis, legs, pairs, size) -> JointMap:
    """Neck, head, tail and torso from what the legs leave (module docstring)."""
    bb = [legs.branch[i] for i in pairs[0]]
    bf = [legs.branch[i] for i in pairs[1]]
    spine = list(dict.fromkeys(_tree_path(par, bb[0], bf[0]) + _tree_path(par, bb[1], bf[1])))
    at_a, at_b, rest, tops = _ends(P, par, active, load, legs, pairs, axis, spine)
    weight = [max((load[p].sum() for p in end), default=0.0) for end in (at_a, at_b)]
    if weight[0] > weight[1]:  # the heavier end is the head's: front is toward it
        axis, pairs = -axis, (pairs[1], pairs[0])
        at_a, at_b, tops = at_b, at_a, [-tops[1], -tops[0]]
        spine = spine[::-1]
    if not at_b:
        raise _refuse(rig, "no chain reaches past the front legs (neck and head)")
    if not at_a:
        raise _refuse(rig, "no chain reaches past the back legs (tail)")
    head_piece = max(at_b, key=lambda p: load[p].sum())
    tail_piece = max(at_a, key=lambda p: tops[0] - float((P[p] @ axis).min()))
    neck_skin, head_skin, behind, neck_chain, head = _neck_head(par, head_piece, P, load,
                                                                axis, tops[1])
    tail_chain, tail_skin, hips = _tail(par, tail_piece, P, load, axis, tops[0], size,
                                           rig, up)
    resolved = {"neck": {"chain": neck_chain, "skinned": neck_skin},
                "head": {"chain": [head], "skinned": head_skin},
                "tail": {"chain": tail_chain, "skinned": tail_skin}}
    left = np.cross(up, axis)
    for i, (chain, root) in enumerate(zip(legs.chains, legs.roots)):
        side = "l" if float((P[legs.feet[i]] - P[spine].mean(0)) @ left) > 0 else "r"
        end = "f" if i in pairs[1] else "b"
        name = f"leg_{end}{side}"
        if name in resolved:
            raise _refuse(rig, f"two legs are both {name} (the feet do not pair left and right)")
        resolved[name] = {"chain": chain, "skinned": root + chain}
    claimed = {j for r in resolved.values() for j in r["skinned"]}
    torso_chain = list(dict.fromkeys(hips[::-1] + _tree_path(par, legs.branch[pairs[0][0]],
                                                             legs.branch[pairs[1][0]])
                                     + behind))
    while len(torso_chain) > 2 and load[torso_chain[-1]] <= 1e-6:
        torso_chain.pop()  # an unskinned end (a root on the ground the legs hang from) is no body
    while len(torso_chain) > 2 and load[torso_chain[0]] <= 1e-6:
        torso_chain.pop(0)
    resolved["torso"] = {"chain": torso_chain,
                         "skinned": [j for j in range(len(par)) if j not in claimed]}
    names = ROLES if template is None else template.names
    return JointMap({g: resolved.get(g, {"chain": [], "skinned": []}) for g in names}, up, axis)


def load_joint_map(path: str | os.PathLike, rig: Rig, template: Template | None = None) -> JointMap:
    """A map file: {<template GC>: [bone, ...] or {joints: [...], skinned: [...]}, frame: {up:
    [x, y, z], front: [x, y, z]}} (frame optional: the template's, or y up and +z front
    without one). Every chain GC of the template (None: the ROLES) must be there."""
    p = Path(path)
    try:
        d = yaml.safe_load(p.read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError) as e:
        raise DataError(f"cannot read the joint map ({type(e).__name__})", path=p) from None
    if not isinstance(d, dict):
        raise DataError("a joint map is a mapping of template GC -> bone names", path=p)
    names = rig.joint_names

    def idx(bones, gc, fld):
        if not isinstance(bones, list) or not all(isinstance(b, str) for b in bones):
            raise DataError("give a list of bone names", path=p, gc=gc, field=fld)
        bad = [b for b in bones if b not in names]
        if bad:
            raise DataError(f"the rig has no bone {bad[0]!r}", path=p, gc=gc, field=fld,
                            fix=f"use the rig's bones ({', '.join(names[:10])}, ...)")
        return [names.index(b) for b in bones]

    resolved = {}
    gcs = [(r, False) for r in ROLES] if template is None else \
        [(g.name, g.carve is not None) for g in template.gcs]
    for name, carved in gcs:
        entry = d.get(name)
        if carved:
            resolved[name] = {"chain": [], "skinned": []}
            continue
        if entry is None:
            raise DataError("the joint map has no entry for this GC", path=p, gc=name,
                            fix=f"add '{name}: [bone, ...]'")
        chain = idx(entry.get("joints") if isinstance(entry, dict) else entry, name, "joints")
        skinned = idx(entry["skinned"], name, "skinned") if isinstance(entry, dict) \
            and "skinned" in entry else chain
        resolved[name] = {"chain": chain, "skinned": skinned}
    frame = d.get("frame") or ({"up": template.up, "front": template.front} if template
                               else {"up": (0.0, 1.0, 0.0), "front": (0.0, 0.0, 1.0)})
    up, front = (np.asarray(frame[k], np.float64) for k in ("up", "front"))
    return JointMap(resolved, up / np.linalg.norm(up), front / np.linalg.norm(front), str(p))
