"""The creatures' parts: the shared GC template (one PartTemplate per GC, in annotation order),
a part's implicit solid in the design frame (`Part`), and a random creature's parts from a
seed (`sample_parts`). `creatures.py` turns them into meshes and annotations."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ngc_gen.data.procedural.implicit import profile_envelope

@dataclass(frozen=True)
class PartTemplate:
    """One GC of the shared template: its name, Bezier degree, frame `up` and the part it grows
    from. Degree and up are fixed per part so every shape has the same parameter layout
    (control points x keys x caps), which the generative shape decoder needs."""

    name: str
    degree: int
    up: tuple[float, float, float]
    parent: str | None


#: The shared template, in the order GCs appear in every annotation (and the smooth-union order).
CREATURE_TEMPLATE: tuple[PartTemplate, ...] = (
    PartTemplate("torso", 3, (0.0, 0.0, 1.0), None),
    PartTemplate("neck", 2, (0.0, 1.0, 0.0), "torso"),
    PartTemplate("head", 2, (0.0, 0.0, 1.0), "neck"),
    PartTemplate("tail", 3, (0.0, 1.0, 0.0), "torso"),
    PartTemplate("leg_fl", 2, (1.0, 0.0, 0.0), "torso"),
    PartTemplate("leg_fr", 2, (1.0, 0.0, 0.0), "torso"),
    PartTemplate("leg_bl", 2, (1.0, 0.0, 0.0), "torso"),
    PartTemplate("leg_br", 2, (1.0, 0.0, 0.0), "torso"),
    PartTemplate("ear_l", 2, (1.0, 0.0, 0.0), "head"),
    PartTemplate("ear_r", 2, (1.0, 0.0, 0.0), "head"),
)
CREATURE_PARTS: tuple[str, ...] = tuple(p.name for p in CREATURE_TEMPLATE)


@dataclass
class Part:
    """One part's implicit solid in the design frame.

    Skeleton: Bezier `points`; radii (r_y, r_z) along the GC frame go from `r0` to `r1` with a
    smoothstep, times a Gaussian bump (`bump` = amplitude, centre t, width); half-ellipsoid ends of
    lengths `caps`; cross-section a lobed superellipse (`exponent`, `lobes`, `lobe_amp`,
    `phase`), turned by a twist lerped from `twist[0]` to `twist[1]` degrees. `blend` is the
    smooth-union radius with which it joins the parts before it.
    """

    name: str
    points: np.ndarray
    up: tuple[float, float, float]
    r0: tuple[float, float]
    r1: tuple[float, float]
    bump: tuple[float, float, float]
    caps: tuple[float, float]
    exponent: float
    lobes: int = 0
    lobe_amp: float = 0.0
    phase: float = 0.0
    twist: tuple[float, float] = (0.0, 0.0)
    blend: float = 0.0

    def radii(self, t: np.ndarray) -> np.ndarray:
        """(N,) normalised arc length -> (N, 2) profile radii (smooth in t)."""
        t = np.asarray(t, np.float64)
        s = (t * t * (3.0 - 2.0 * t))[:, None]
        amp, tc, w = self.bump
        bump = 1.0 + amp * np.exp(-(((t - tc) / w) ** 2))[:, None]
        return (np.asarray(self.r0) * (1.0 - s) + np.asarray(self.r1) * s) * bump

    @property
    def envelope(self) -> float:
        return profile_envelope(self.exponent, self.lobe_amp)

    def mirrored(self, name: str) -> "Part":
        """The mirror image across the y = 0 plane (lobes mirror too)."""
        pts = self.points * np.array([1.0, -1.0, 1.0])
        return Part(name, pts, self.up, self.r0, self.r1, self.bump, self.caps, self.exponent,
                    self.lobes, self.lobe_amp, -self.phase, (-self.twist[0], -self.twist[1]),
                    self.blend)


# ---- random parts ---------------------------------------------------------------------------
def _bezier(p0, p_end, degree: int, offsets) -> np.ndarray:
    """Control points of a Bezier of `degree` from p0 to p_end: the straight line's evenly
    spaced points with the inner ones moved by `offsets` ((degree - 1, 3))."""
    p0, p_end = np.asarray(p0, np.float64), np.asarray(p_end, np.float64)
    s = np.linspace(0.0, 1.0, degree + 1)[:, None]
    pts = p0 * (1.0 - s) + p_end * s
    pts[1:-1] += np.asarray(offsets, np.float64).reshape(degree - 1, 3)
    return pts


def sample_parts(seed: int) -> list[Part]:
    """Random creature parts in the design frame (about 1.2-1.8 long), in template order.

    Proportions (body, legs, neck, head, ears, tail), skeleton curvature (arched back, bent
    neck, knees, curled tail, swept ears), radius profiles (chest/hip, paws, cranium, bushy tail
    tip) and cross-sections (superellipse exponent 2.5-4, lobes on legs/tail/torso) all vary.
    The parts draw from one generator in a fixed order (torso, neck and head, tail, legs, ears),
    so a seed always gives the same creature."""
    rng = np.random.default_rng(seed)
    deg = {p.name: p.degree for p in CREATURE_TEMPLATE}
    up = {p.name: p.up for p in CREATURE_TEMPLATE}
    torso, body = _torso(rng, deg, up)
    neck, head, skull = _neck_and_head(rng, deg, up, body)
    tail = _tail(rng, deg, up, body)
    legs = _legs(rng, deg, up, body)
    ear = _ear(rng, deg, up, skull)
    parts = {"torso": torso, "neck": neck, "head": head, "tail": tail, **legs,
             "ear_l": ear, "ear_r": ear.mirrored("ear_r")}
    return [parts[n] for n in CREATURE_PARTS]


def _torso(rng, deg: dict, up: dict) -> tuple[Part, dict]:
    """The torso and the body's sizes the other parts attach to."""
    U = rng.uniform
    # torso along x; frame y = vertical, frame z = lateral
    L = U(0.55, 0.85)
    r_vert = U(0.12, 0.18)
    r_lat = r_vert * U(0.9, 1.3)
    H = U(0.28, 0.55)  # leg length
    zc = H + 0.3 * r_vert
    arch, rise = U(-0.03, 0.06), U(-0.02, 0.06)
    torso_pts = _bezier([-L / 2, 0, zc - rise / 2], [L / 2, 0, zc + rise / 2], deg["torso"],
                        [[U(-0.03, 0.03), 0, arch + U(-0.02, 0.02)] for _ in range(2)])
    hip, chest = U(0.8, 1.05), U(0.95, 1.2)
    torso = Part("torso", torso_pts, up["torso"], (r_vert * hip, r_lat * hip),
                 (r_vert * chest, r_lat * chest), (U(0.0, 0.12), U(0.35, 0.65), U(0.2, 0.35)),
                 (U(0.6, 1.0) * r_vert * hip, U(0.6, 1.0) * r_vert * chest), U(2.6, 4.0),
                 lobes=int(rng.integers(5, 9)), lobe_amp=U(0.0, 0.04), phase=U(0, 2 * np.pi))
    return torso, {"L": L, "r_vert": r_vert, "r_lat": r_lat, "zc": zc, "rise": rise}


def _neck_and_head(rng, deg: dict, up: dict, body: dict) -> tuple[Part, Part, dict]:
    """Neck and head, and the head's frame the ears attach to."""
    U = rng.uniform
    L, r_vert, zc, rise = body["L"], body["r_vert"], body["zc"], body["rise"]
    # neck: from inside the chest up and forward; frame y = lateral
    a_n = math.radians(U(35.0, 75.0))
    d_n = np.array([math.cos(a_n), 0.0, math.sin(a_n)])
    perp_n = np.array([-math.sin(a_n), 0.0, math.cos(a_n)])
    n0 = np.array([L / 2 - 0.35 * r_vert, 0.0, zc + rise / 2 + 0.3 * r_vert])
    n1 = n0 + U(0.2, 0.45) * d_n
    r_neck = U(0.055, 0.09)
    neck = Part("neck", _bezier(n0, n1, deg["neck"], [U(-0.05, 0.05) * perp_n]), up["neck"],
                (r_neck, r_neck * U(0.85, 1.15)), (r_neck * U(0.65, 0.9), r_neck * U(0.65, 0.9)),
                (U(0.0, 0.15), U(0.4, 0.7), 0.25), (0.5 * r_neck, 0.5 * r_neck), U(2.5, 3.5),
                blend=U(0.05, 0.08))

    # head: from behind the neck's end toward the snout; frame y = vertical
    Rh = U(0.09, 0.14)
    Lh = U(0.12, 0.26)
    pitch = math.radians(U(-20.0, 10.0))
    d_h = np.array([math.cos(pitch), 0.0, math.sin(pitch)])
    perp_h = np.array([-math.sin(pitch), 0.0, math.cos(pitch)])
    h0 = n1 - 0.1 * Lh * d_h + 0.35 * Rh * perp_h
    h1 = h0 + Lh * d_h
    head_r0 = (Rh * U(0.85, 1.1), Rh * U(0.9, 1.15))
    snout = U(0.4, 0.75)
    head_r1 = (head_r0[0] * snout, head_r0[1] * snout)
    head = Part("head", _bezier(h0, h1, deg["head"], [U(-0.03, 0.02) * perp_h]), up["head"],
                head_r0, head_r1, (U(0.05, 0.2), U(0.15, 0.35), 0.25),
                (U(0.7, 1.0) * Rh, U(0.5, 1.0) * snout * Rh), U(2.3, 3.2),
                blend=U(0.03, 0.06))
    return neck, head, {"h0": h0, "Lh": Lh, "d_h": d_h, "Rh": Rh}


def _tail(rng, deg: dict, up: dict, body: dict) -> Part:
    U = rng.uniform
    L, r_vert, zc, rise = body["L"], body["r_vert"], body["zc"], body["rise"]
    # tail: from inside the rump backward and up, curled, twisted lobes, bushy tip
    a_t = math.radians(U(-30.0, 60.0))
    d_t = np.array([-math.cos(a_t), 0.0, math.sin(a_t)])
    perp_t = np.array([math.sin(a_t), 0.0, math.cos(a_t)])
    t0 = np.array([-L / 2 + 0.3 * r_vert, 0.0, zc - rise / 2 + 0.2 * r_vert])
    Lt = U(0.2, 0.5)
    r_tail = U(0.03, 0.055)
    r_tip = max(r_tail * U(0.35, 0.7), 0.02)
    tail = Part("tail", _bezier(t0, t0 + Lt * d_t, deg["tail"],
                                [U(-0.08, 0.08) * perp_t for _ in range(2)]), up["tail"],
                (r_tail, r_tail), (r_tip, r_tip), (U(0.0, 0.8), U(0.75, 0.92), 0.12),
                (0.5 * r_tail, U(0.8, 1.8) * r_tip), U(2.5, 3.5),
                lobes=int(rng.integers(3, 7)), lobe_amp=U(0.05, 0.15), phase=U(0, 2 * np.pi),
                twist=(0.0, U(-180.0, 180.0)), blend=U(0.03, 0.06))
    return tail


def _legs(rng, deg: dict, up: dict, body: dict) -> dict[str, Part]:
    U = rng.uniform
    L, r_lat, zc = body["L"], body["r_lat"], body["zc"]
    # legs: from inside the torso straight down, splayed outward (T-pose-like), knees, paws;
    # frame y = forward, frame z = lateral. Right legs mirror the left ones.
    legs = {}
    # (name, hip x, knee range along x): front knees forward, hind hocks back
    for name, x, knee in (("leg_fl", L * (0.5 - U(0.12, 0.2)), (-0.02, 0.06)),
                          ("leg_bl", -L * (0.5 - U(0.12, 0.22)), (-0.07, 0.02))):
        y = U(0.55, 0.8) * r_lat
        r_leg = U(0.045, 0.075)
        r_end = r_leg * U(0.6, 0.9)
        paw = U(0.15, 0.5)
        foot = r_end * (1 + paw) * U(0.6, 0.9)
        p0 = [x, y, zc]
        p1 = [x + U(-0.03, 0.03), y + U(0.04, 0.16), foot]
        legs[name] = Part(name, _bezier(p0, p1, deg[name], [[U(*knee), U(0.0, 0.03), 0.0]]),
                          up[name], (r_leg, r_leg * U(0.9, 1.15)), (r_end, r_end),
                          (paw, U(0.9, 1.0), 0.12), (0.5 * r_leg, foot), U(2.5, 3.5),
                          lobes=int(rng.integers(4, 7)), lobe_amp=U(0.0, 0.1),
                          phase=U(0, 2 * np.pi), blend=U(0.04, 0.07))
    legs["leg_fr"] = legs["leg_fl"].mirrored("leg_fr")
    legs["leg_br"] = legs["leg_bl"].mirrored("leg_br")
    return legs


def _ear(rng, deg: dict, up: dict, skull: dict) -> Part:
    """The left ear (the right one mirrors it)."""
    U = rng.uniform
    h0, Lh, d_h, Rh = skull["h0"], skull["Lh"], skull["d_h"], skull["Rh"]
    # ears: from inside the skull up and outward, flat (frame y = thickness ~ x), tapered
    Le = U(0.08, 0.3)
    e0 = h0 + U(0.1, 0.35) * Lh * d_h + np.array([0.0, U(0.3, 0.6) * Rh, 0.55 * Rh])
    d_e = np.array([-U(0.0, 0.4), U(0.15, 0.8), 1.0])
    d_e /= np.linalg.norm(d_e)
    width = max(U(0.3, 0.55) * Le, 0.04)
    thick = U(0.022, 0.03)
    ear = Part("ear_l", _bezier(e0, e0 + Le * d_e, deg["ear_l"],
                                [[U(-0.04, 0.02), U(-0.02, 0.03), 0.0]]), up["ear_l"],
               (thick, width), (thick * U(0.7, 0.9), max(width * U(0.3, 0.7), 0.025)),
               (U(0.0, 0.3), U(0.3, 0.6), 0.25), (0.5 * width, U(0.5, 1.2) * width * 0.5),
               U(2.5, 3.5), blend=U(0.015, 0.03))
    return ear
