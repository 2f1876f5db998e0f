"""Right names or a refusal: a match checked against what the template says about itself.

After the correspondence, in the body frame of the orientation tried (front, left, up of the
surface's bounding box over its half extents), each check compares where the matched parts lie
with where the template's `place` puts them:
- ends: the parts off the torso's middle (neck, head, tail) lie on the template's side of the
  torso, front or back (head and tail at opposite ends, the neck toward the head);
- ground: the parts that reach down (legs) end below the torso's middle, all of them;
- downward: the legs' directions (root to foot, in the frame's lengths) point down within
  DOWNWARD on average: a body laid on its side reads ears, a tail or a neck as legs that run
  sideways and dip just below the torso, passing `ground`;
- spine (asked for a frame the search detected): the torso's path (between where the limbs
  join it), or the back (from the hind legs' roots to the front legs', both pairs matched),
  runs as the template's does, front to back, within SPINE_DEG in the frame's own lengths
  (the half extents); either passes: a frame that stands the body on end, a tall animal turned
  about the line between its back and its neck (front and up swapped, the neck taken for the
  back, front legs for a tail, hind legs pointing backwards), puts every tip where the
  template's is in the box-scaled coordinates the match reads, as well as the right frame
  does; only the body's own direction tells them. An elephant's torso path runs up into the
  neck's base (40+ degrees off in a nearly right frame) while its back stays level; a gallop's
  crossed legs turn the back around while the torso's path stays right. Not asked of given
  axes, an override or a frame levelled on its feet: their up does not come from the search;
- legs: the parts that reach down are alike in thickness, the thickest's outer half (a shin, a
  forearm) at most LEGS_RATIO x the thinnest's: a frame turned back to front in a gallop may
  take the head, or a bushy tail, for a hind leg and pass every other check;
- sides: of a symmetric pair, the part the template puts on the left lies left of its partner,
  and no sided part lies more than SIDE across the torso's middle (a path down one leg and up
  the other, two legs joined at the feet, named for the wrong one while its partner is missing);
- mirror: a symmetric pair's paths are alike in length (within MIRROR_RATIO);
- weight: of the two ends, the one whose parts the template makes HEAVY_RATIO x larger (neck and
  head against the tail: their surface, radius x length) does not hold clearly less (LIGHTER x)
  of the mesh's surface than the other (the samples nearest the tree nodes each GC labels, horns
  and ears with their head): a frame turned back to front is consistent in itself, and only this
  tells it (the head's chain on the tail).
  The surface, not the thickness along a path: a head's path may end on a horn, thinner than a
  tail, and a stubby tail's path runs inside the rump. Each leg holds at least LEG_WEIGHT x
  its template share (radius x length) of the matched parts' surface: a body upside down reads
  its ears as hind legs.
The first failing check names the mesh's refusal when no orientation passes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ngc_gen.data.autogc.template import Template

from .leg_order import reaches_down

END_FRONT = 0.3    # a part whose place's middle lies this far (body units) front or back is an end
SIDE = 0.2         # a symmetric part this far left or right tells left from right
MIRROR_RATIO = 2.5  # a symmetric pair's path lengths differ by at most this factor
HEAVY_RATIO = 2.0  # an end whose parts are this much larger in the template (neck and head: about
                   # 4x the tail) must not hold clearly less of the mesh's surface than the other
LIGHTER = 0.8      # end: less than this share of it (a thick tail as long as the neck: alike)
LEGS_RATIO = 2.5   # legs' outer halves: the thickest at most this x the thinnest (alike: 1.0-1.6)
DOWNWARD = 0.5     # legs' mean downward share of their direction (cos 60 degrees; legs of a
                   # standing or galloping animal: 0.85-1.0, a sprawling crocodile's 0.6)
LEG_WEIGHT = 0.25  # a leg holds at least this x its template share of the matched parts' surface
                   # (legs of one animal: 0.3-1.2; an ear taken for a leg: 0.2)
SPINE_DEG = 35.0   # the torso's path or the back runs within this of the template's (a jump or a gallop
                   # pitches the back by up to about 20 degrees; a frame standing it on end, 40+)


@dataclass(frozen=True)
class Verdict:
    """failed: the first check that failed, with what it saw (None: all passed)."""

    failed: str | None

    @property
    def ok(self) -> bool:
        return self.failed is None



def _mid(place: dict) -> np.ndarray:
    return (np.asarray(place["start"], float) + np.asarray(place["end"], float)) / 2.0


def verify(template: Template, paths: dict[str, np.ndarray], nodes_body: np.ndarray,
           surface: np.ndarray, half: np.ndarray | None = None,
           radius: np.ndarray | None = None, spine: bool = False) -> Verdict:
    """The checks of the module docstring on matched `paths` (template GC name -> node indices,
    root side first) with the tree's nodes in body coordinates `nodes_body` (N, 3), the share
    of the mesh's surface each template GC holds, `surface` (G,) in template order, and the
    frame's half extents `half` (3,) (body units to lengths; None: alike) and the tree's
    thickness at each node `radius` (N,) (None: the legs check is skipped); spine: with the
    spine check."""
    root = template.root
    if root not in paths:
        return Verdict(f"no {root} found")
    torso = nodes_body[paths[root]].mean(0)
    t_torso = _mid(template.gc(root).place)
    for g in template.gcs:
        if g.name == root or g.name not in paths:
            continue
        p, pl = nodes_body[paths[g.name]], g.place
        down = reaches_down(pl)
        side = _mid(pl)[0] - t_torso[0]
        if not down and abs(side) >= END_FRONT and np.sign(p.mean(0)[0] - torso[0]) != np.sign(side):
            where = "front" if side > 0 else "back"
            return Verdict(f"ends: {g.name} is not at the {where} of the {root} (head and tail "
                           "at opposite ends, the neck toward the head)")
        if down and p[-1][2] >= torso[2]:
            return Verdict(f"ground: {g.name} does not reach down below the {root}")
    failed = _spine(template, paths, nodes_body, np.ones(3) if half is None
                    else np.asarray(half, dtype=np.float64)) if spine else None
    if failed:
        return Verdict(failed)
    failed = _downward(template, paths, nodes_body, half) or \
        _weight(template, paths, surface, root, t_torso) or \
        _leg_weight(template, paths, surface, root) or \
        (_legs(template, paths, radius) if radius is not None else None)
    if failed:
        return Verdict(failed)
    for g in template.gcs:
        side = _mid(g.place)[1]
        if g.name in paths and abs(side) >= SIDE and \
                np.sign(side) * (nodes_body[paths[g.name]].mean(0)[1] - torso[1]) < -SIDE:
            return Verdict(f"sides: {g.name} lies {'right' if side > 0 else 'left'} of the "
                           f"{root}'s middle, past {SIDE} (left and right swapped)")
    for g in template.gcs:
        s = g.symmetric
        if s is None or g.name not in paths or s not in paths or _mid(g.place)[1] < SIDE:
            continue
        left, right = nodes_body[paths[g.name]], nodes_body[paths[s]]
        if left.mean(0)[1] <= right.mean(0)[1]:
            return Verdict(f"sides: {g.name} lies right of {s} (left and right swapped)")
        la, lb = (float(np.linalg.norm(np.diff(x, axis=0), axis=1).sum()) for x in (left, right))
        if max(la, lb) > MIRROR_RATIO * max(min(la, lb), 1e-9):
            return Verdict(f"mirror: {g.name} and {s} differ in length {la / max(lb, 1e-9):.1f}x "
                           "(not mirror images)")
    return Verdict(None)


def _spine(template: Template, paths: dict, nodes_body: np.ndarray,
           half: np.ndarray) -> str | None:
    """The spine check (module docstring): None when it passes."""
    root = template.gc(template.root)
    p = nodes_body[paths[root.name]]
    runs = {root.name: (p[-1] - p[0], np.subtract(root.place["end"], root.place["start"]))}
    legs = {end: [g for g in template.gcs if g.parent == root.name and g.name in paths and
                  reaches_down(g.place) and np.sign(_mid(g.place)[0] - _mid(root.place)[0]) == end]
            for end in (1, -1)}
    if all(legs.values()):  # the back itself: from the hind legs' roots to the front legs'
        at = {e: (np.mean([nodes_body[paths[g.name][0]] for g in gs], 0),
                  np.mean([g.place["start"] for g in gs], 0)) for e, gs in legs.items()}
        runs["back"] = (at[1][0] - at[-1][0], at[1][1] - at[-1][1])
    deg = {}
    for what, (got, want) in runs.items():
        got, want = got * half, want * half
        cos = float(got @ want) / max(float(np.linalg.norm(got) * np.linalg.norm(want)), 1e-12)
        deg[what] = float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
    if min(deg.values()) > SPINE_DEG:
        return ("spine: the " + " and the ".join(f"{w} runs {d:.0f}" for w, d in deg.items()) +
                f" degrees off the template's, at most {SPINE_DEG:.0f} (the body stood on end?)")
    return None


def _downward(template: Template, paths: dict, nodes_body: np.ndarray,
              half: np.ndarray | None) -> str | None:
    """The downward check (module docstring): None when it passes."""
    h = np.ones(3) if half is None else np.asarray(half, dtype=np.float64)
    d = [(nodes_body[paths[g.name][-1]] - nodes_body[paths[g.name][0]]) * h
         for g in template.gcs
         if g.name in paths and len(paths[g.name]) >= 2 and reaches_down(g.place)]
    if not d:
        return None
    down = float(np.mean([-v[2] / max(float(np.linalg.norm(v)), 1e-12) for v in d]))
    if down < DOWNWARD:
        return (f"downward: the legs run {np.degrees(np.arccos(np.clip(down, -1, 1))):.0f} "
                f"degrees off down on average, at most "
                f"{np.degrees(np.arccos(DOWNWARD)):.0f} (the body laid on its side or back?)")
    return None


def _leg_weight(template: Template, paths: dict, surface: np.ndarray,
                root: str) -> str | None:
    """The leg weight check (module docstring): None when it passes."""
    parts = [g for g in template.gcs if g.name in paths and g.name != root]
    size = {g.name: g.place["radius"] * float(np.linalg.norm(np.subtract(g.place["end"],
                                                                          g.place["start"])))
            for g in parts}
    held = {g.name: float(surface[template.names.index(g.name)]) for g in parts}
    total_size, total_held = sum(size.values()), max(sum(held.values()), 1e-12)
    for g in parts:
        if not reaches_down(g.place):
            continue
        ratio = (held[g.name] / total_held) / max(size[g.name] / total_size, 1e-12)
        if ratio < LEG_WEIGHT:
            return (f"weight: {g.name} holds {held[g.name]:.1%} of the surface, "
                    f"{ratio:.2f}x its template share, at least {LEG_WEIGHT} (an ear or a tail "
                    "taken for a leg: the body upside down?)")
    return None


def _legs(template: Template, paths: dict, radius: np.ndarray) -> str | None:
    """The legs check (module docstring): None when it passes."""
    r = {g.name: float(np.median(radius[paths[g.name][len(paths[g.name]) // 2:]]))
         for g in template.gcs if g.name in paths and len(paths[g.name]) >= 2 and
         reaches_down(g.place)}
    if len(r) < 2:
        return None
    thick, thin = max(r, key=r.get), min(r, key=r.get)
    if r[thick] > LEGS_RATIO * max(r[thin], 1e-12):
        return (f"legs: {thick} is {r[thick] / max(r[thin], 1e-12):.1f}x as thick as {thin}, at "
                f"most {LEGS_RATIO} (a head or a tail taken for a leg: front and back swapped?)")
    return None


def _weight(template: Template, paths: dict, surface: np.ndarray, root: str,
            t_torso: np.ndarray) -> str | None:
    """The weight check (module docstring): None when it passes."""
    ends: dict[int, list] = {1: [], -1: []}
    for g in template.gcs:
        side = _mid(g.place)[0] - t_torso[0]
        if g.name != root and not reaches_down(g.place) and \
                abs(side) >= END_FRONT:
            ends[int(np.sign(side))].append(g)
    if not all(any(g.name in paths for g in e) for e in ends.values()):
        return None  # one end has nothing matched: nothing to weigh
    size = {s: sum(g.place["radius"] * float(np.linalg.norm(np.subtract(g.place["end"],
                   g.place["start"]))) for g in e) for s, e in ends.items()}
    held = {s: sum(float(surface[template.names.index(g.name)]) for g in e)
            for s, e in ends.items()}
    for heavy, light in ((1, -1), (-1, 1)):
        if size[heavy] >= HEAVY_RATIO * size[light] and held[heavy] < LIGHTER * held[light]:
            who = {s: " and ".join(g.name for g in e if g.name in paths) for s, e in ends.items()}
            return (f"weight: {who[heavy]} hold {held[heavy]:.1%} of the surface, {who[light]} "
                    f"{held[light]:.1%} (the template's are {size[heavy] / size[light]:.1f}x "
                    "larger: front and back swapped?)")
    return None
