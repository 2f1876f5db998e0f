"""Which way a mesh faces, for a template: the orientation whose match passes the template's
checks at the lowest cost (docs/transfer.md, "Orientation").

Tried per mesh: the user's override alone when there is one; else the given axes (a prior),
the axis-snapped detection of ``orient`` and the 16 principal-axis frames of ``frame``. Each
detected candidate is matched, turned to the frame its matched parts imply (``frame.wahba``:
every matched GC's path direction against its template place's), snapped to the signed world
axes when within SNAP_DEG of them, and matched again; then checked (``verify``). The given
axes are kept when they pass and cost at most PRIOR_SLACK more than the best detected frame,
else overruled with a warning. A detected frame is then levelled on its matched feet
(``_levelled``). Nothing passes: DataError naming the failed check.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ngc_gen.data.autogc.frame import angle_deg, distinct, orientation_of, pca_candidates, wahba
from ngc_gen.data.autogc.orient import Orientation, axis_name, detect_orientation
from ngc_gen.data.autogc.template import Template
from ngc_gen.data.errors import DataError

from .leg_order import reaches_down
from .match import _tips, correspond
from .tree import BodyFrame, extreme_points
from .verify import verify

SNAP_DEG = 10.0     # a detected frame this close to signed world axes is snapped to them
PRIOR_SLACK = 0.5   # given axes stay unless a detected frame matches this much cheaper
DISTINCT_DEG = 30.0  # the runner-up for the confidence: a frame at least this far away that
                     # puts some name on another part
REFINE_ROUNDS = 2  # a detected candidate is turned to its match's implied frame this many times
LEAF_WEIGHT = 0.5   # a swinging limb's direction counts this much in the implied frame
LEVEL_FLAT = 0.15   # feet lie on one plane: the least spread across it over the next (4+ feet)
LEVEL_DEG = (2.0, 45.0)  # a frame whose feet's plane is tilted this much is levelled on them
TILT_DEG = 25.0     # each candidate also tilted this much about its left and its up axis: a long
                    # neck or tail turns the principal axes off the body's (a donkey's by 21
                    # degrees), too far for the match to start from


@dataclass
class Trial:
    """One orientation tried: its body frame, the match (or the error refusing it), the
    failed check (None: passed) and the match's score (lower is better)."""

    orientation: Orientation
    body: object
    found: tuple | DataError
    failed: str | None
    score: float


@dataclass
class Choice:
    """The orientation chosen, its trial, how sure (0-1: 1 - its score over the best other
    passing frame's that names the parts otherwise) and warnings for the user (a prior
    overruled)."""

    trial: Trial
    confidence: float
    warnings: list[str]


def _snap(o: Orientation) -> Orientation:
    """The signed-axis frame nearest `o` when within SNAP_DEG of it, else `o`."""
    def ax(v):
        a = int(np.argmax(np.abs(v)))
        out = np.zeros(3)
        out[a] = np.sign(v[a])
        return out

    up, front = ax(o.up), ax(o.front)
    if abs(up @ front) > 0.5:
        return o
    s = Orientation(up, front, o.source)
    return s if angle_deg(s.matrix @ o.matrix.T) <= SNAP_DEG else o


def tilted(orientations: list[Orientation]) -> list[Orientation]:
    """Each orientation, then the same turned by +-TILT_DEG about its left axis (head up or
    down) and about its up axis (head left or right)."""
    out = list(orientations)
    for o in orientations:
        for axis in (o.left, o.up):
            for sign in (1.0, -1.0):
                R = Rotation.from_rotvec(np.radians(sign * TILT_DEG) * axis).as_matrix()
                out.append(Orientation(R @ o.up, R @ o.front, o.source))
    return out


def _score(found, T: int, missing_cost: float) -> float:
    _, _, missing, cost = found
    return (cost * (T - len(missing)) + missing_cost * len(missing)) / max(T, 1)


def _implied(template: Template, tree, body, paths: dict, leaves: set) -> np.ndarray:
    """The rotation (rows front, left, up) in which the matched paths point as the template's
    places do, in this mesh's half extents (``frame.wahba``)."""
    world, want, w = [], [], []
    for name, p in paths.items():
        if len(p) < 2:
            continue
        pl = template.gc(name).place
        t = (np.asarray(pl["end"], float) - np.asarray(pl["start"], float)) * body.half
        world.append(tree.nodes[p[-1]] - tree.nodes[p[0]])
        want.append(t)
        w.append(float(np.linalg.norm(t)) * (LEAF_WEIGHT if name in leaves else 1.0))
    return wahba(np.asarray(world), np.asarray(want), np.asarray(w))


def _try(ctx, o: Orientation, refine: bool) -> Trial:
    """The orientation matched and checked; refined (a detected candidate, checked with the
    spine too): turned to its match's implied frame REFINE_ROUNDS times, the best of the rounds
    kept (passing first, then the lower score: a round may turn a frame that matched into one
    that does not)."""
    template, tree, surface, st, where, T, leaves, share = ctx
    best = None
    for step in range(1 + REFINE_ROUNDS if refine else 1):
        body = BodyFrame.of(surface, o)
        try:
            found = correspond(template, tree, body, st, where)
        except DataError as e:
            trial = Trial(o, body, e, str(e.what), float("inf"))
        else:
            held = np.bincount(found[1], weights=share, minlength=len(template.gcs))
            verdict = verify(template, found[0], body.to_body(tree.nodes), held, body.half,
                            tree.radius, spine=refine)
            trial = Trial(o, body, found, verdict.failed, _score(found, T, st.missing_cost))
        if best is None or (trial.failed is None, -trial.score) > (best.failed is None, -best.score):
            best = trial
        if not isinstance(trial.found, tuple) or step == REFINE_ROUNDS or not refine:
            break
        o = _snap(orientation_of(_implied(template, tree, body, found[0], leaves), o.source))
    return best


def ground_up(feet: np.ndarray, up: np.ndarray) -> np.ndarray | None:
    """The normal (on `up`'s side) of the plane the feet (K, 3), K >= 4, lie on, when they lie
    on one (the least spread across it at most LEVEL_FLAT x the next) tilted from `up` within
    LEVEL_DEG; else None."""
    if len(feet) < 4:
        return None
    _, s, Vt = np.linalg.svd(feet - feet.mean(0))
    n = Vt[2] * (np.sign(Vt[2] @ up) or 1.0)
    tilt = float(np.degrees(np.arccos(np.clip(n @ up, -1.0, 1.0))))
    ok = s[2] <= LEVEL_FLAT * s[1] and LEVEL_DEG[0] <= tilt <= LEVEL_DEG[1]
    return n if ok else None


def _levelled(ctx, trial: Trial) -> Trial:
    """The trial turned so that its matched feet (the legs' ends) lie on one level plane, the
    ground, when they do lie on one (4+ feet within LEVEL_FLAT) tilted within LEVEL_DEG: kept
    when it passes and puts every leg on the same foot. The match's cost prefers the frame
    in which a long neck points as the template's does (a giraffe tilted 35 degrees); the
    ground under the feet does not depend on the neck."""
    template, tree = ctx[0], ctx[1]
    paths = trial.found[0]
    feet = [n for n, p in paths.items() if len(p) >= 2 and
            reaches_down(template.gc(n).place)]
    if len(feet) < 4:
        return trial
    o = trial.orientation
    up = ground_up(tree.nodes[[int(paths[n][-1]) for n in feet]], o.up)
    if up is None:
        return trial
    axis = np.cross(o.up, up)
    angle = np.arccos(np.clip(up @ o.up, -1.0, 1.0))
    R = Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle).as_matrix()
    level = _try(ctx, Orientation(up, R @ o.front, o.source), refine=False)
    same = all(_ends(level).get(n) == _ends(trial)[n] for n in feet)
    return level if level.failed is None and same else trial


def _ends(trial: Trial) -> dict:
    """Where each matched GC's path ends: two frames that put every name on the same parts
    read the mesh alike, however far apart they are."""
    return {n: int(p[-1]) for n, p in trial.found[0].items()} if isinstance(trial.found, tuple) \
        else {}


def choose(template: Template, tree, surface: np.ndarray, share: np.ndarray, st, where, curves,
           volumes, up, front, override: Orientation | None) -> Choice:
    """The orientation for this mesh (module docstring); share (N,): the surface nearest each
    tree node (``tree.surface_share``)."""
    tips = _tips(template)[0]
    ctx = (template, tree, extreme_points(surface), st, where, len(tips), set(tips), share)
    if override is not None:
        trial = _try(ctx, override, refine=False)
        if trial.failed:
            raise DataError(f"does not match template {template.name} in the frame override "
                            f"({override.describe()}): {trial.failed}", path=where,
                            field="frame", fix="correct the frame override, or remove it to detect")
        return Choice(trial, 1.0, [])
    prior = None
    if up is not None or front is not None:
        prior = _try(ctx, detect_orientation(curves, volumes, None, up, front, surface), False)
    cands = distinct(tilted([detect_orientation(curves, volumes, None, None, None, surface),
                             *pca_candidates(surface)]))
    trials = [_try(ctx, o, refine=True) for o in cands]
    passing = sorted((t for t in trials if t.failed is None), key=lambda t: t.score)
    best = passing[0] if passing else None
    warnings = []
    if prior is not None and prior.failed is None and \
            (best is None or prior.score <= best.score + PRIOR_SLACK):
        best = prior
    elif prior is not None and best is not None:
        warnings.append(f"given axes ({prior.orientation.describe()}) overruled: "
                        f"{prior.failed or f'cost {prior.score:.2f}'}; detected up "
                        f"{axis_name(best.orientation.up)}, front {axis_name(best.orientation.front)}")
    if best is None:
        tried = [t for t in ([prior] if prior else []) + trials]
        first = min(tried, key=lambda t: (not isinstance(t.found, tuple), t.score))
        if isinstance(first.found, DataError):
            raise first.found
        raise DataError(f"does not match template {template.name} ({template.source}) in any of "
                        f"{len(tried)} orientations; the best failed the check {first.failed}",
                        path=where, field="annotate.template",
                        fix="give the mesh's frame (frame: {up: +y, front: -z} in its YAML or "
                            "the folder's frames.yaml), or annotate it by hand")
    others = [t.score for t in passing if t is not best and _ends(t) != _ends(best) and
              angle_deg(t.orientation.matrix @ best.orientation.matrix.T) > DISTINCT_DEG]
    second = min(others) if others else st.max_match_cost
    confidence = float(np.clip(1.0 - best.score / max(second, 1e-9), 0.0, 1.0))
    if confidence < st.min_confidence and best is not prior:
        raise DataError(f"does not match template {template.name} ({template.source}) in one "
                        f"way: two frames {DISTINCT_DEG:.0f}+ degrees apart fit alike (confidence "
                        f"{confidence:.2f}, need {st.min_confidence})", path=where,
                        field="annotate.template",
                        fix="give the mesh's frame (frame: {up: +y, front: -z} in its YAML or the "
                            "folder's frames.yaml), or annotate it by hand")
    return Choice(best if best is prior else _levelled(ctx, best), confidence, warnings)
