"""A posed rig -> a closed, normalised mesh and the template's GCs on it.

1. Pose the rig (linear blend skinning) and close the posed mesh by the closed proxy (several
   open pieces become one watertight surface), then normalise it as every mesh of the data
   layer is (bounding box into [-bound, bound]^3).
2. Every surface sample belongs to the template GC that holds most of its skin weight (the
   weights of a GC's chain and `skinned` joints summed; the proxy's samples take the weights
   of the nearest point of the posed mesh).
3. Per GC: a least-squares Bezier of the template's degree through its chain's posed joints,
   extended to the surface past the ends the template marks free (a one-joint chain along
   its bone); the frame starts from the
   template's `up`; radii per key are the smallest ellipses holding the GC's own samples near
   the key, caps the extent of those past the ends.
   A carved GC (template `carve`, for a part without joints: the stag's antlers) takes the
   samples of its source GC's own surface that stand out of the source's core GC (fitted to
   the samples near its axis, then refitted without those) on its side; its curve runs from
   where they leave the source through their centroids binned by distance from there (a small
   GC at the source's first joint where the rig has no such part).
4. Coverage repair (`grow_to_cover`): each GC first grows to hold its own samples near it,
   then every fitting sample left outside goes to the relatively nearest GC; coverage and
   purity (the share of a GC's own samples inside it) are measured on fresh samples.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from ngc_gen.conf.defaults import yaml_settings
from ngc_gen.data.annotations import rounded_gc_dict
from ngc_gen.data.autogc.coverage import grow_to_cover, rho_matrix
from ngc_gen.data.autogc.radii import ellipse_radii
from ngc_gen.data.autogc.template import Template, TemplateGC
from ngc_gen.data.errors import DataError
from ngc_gen.data.group_settings import from_group
from ngc_gen.data.mesh.io import normalize
from ngc_gen.data.mesh.proxy import closed_proxy
from ngc_gen.data.mesh.sampling import gc_membership, sample_surface
from ngc_gen.geometry import GeneralizedCylinder, GeometryError, bernstein_basis

from .rig import Rig

OUTLIER = 1.6  # a sample farther out than this x its key window's median is left to growth
#: a GC first grows to hold its own samples within this relative distance (rho) of it; the rest
#: of the surface then goes to whichever GC is relatively nearest
OWN_REACH = 2.0
#: a carved GC (template `carve`) takes the samples of its source GC's own surface farther than
#: this relative distance (rho) from the source's core GC (fitted without them)
CARVE_REACH = 1.25
#: fewer carved samples than this: the part is absent, and the GC is a small one at the source's
#: first joint (every shape keeps the same layout)
CARVE_MIN = 40
#: the core GC a carve is measured against keeps, per key window, the samples nearer its axis
#: than 1.3 x the window's 30% quantile (an antler can be most of a window's samples)
CORE_TRIM = (0.3, 1.3)


@dataclass(frozen=True)
class RigGCSettings:
    """How posed rigs become GCs; the values live in conf/data/animals.yaml's `gcs`
    (`from_yaml`, `from_config`). resolution: proxy voxels along the longest side; samples: surface
    samples the GCs are fitted to and grown to cover; check_samples: fresh samples coverage
    and purity are measured on; margin: radii and caps grown by this share; bound: the
    normalisation; min_coverage: below it the shape is refused."""

    resolution: int
    samples: int
    check_samples: int
    margin: float
    bound: float
    min_coverage: float
    seed: int

    def __post_init__(self):
        checks = {"resolution": self.resolution >= 32, "samples": self.samples >= 1000,
                  "check_samples": self.check_samples >= 1000, "margin": self.margin >= 0,
                  "bound": self.bound > 0, "min_coverage": 0 <= self.min_coverage <= 1}
        for name, ok in checks.items():
            if not ok:
                raise DataError(f"invalid value {getattr(self, name)!r}", field=f"data.gcs.{name}",
                                fix="resolution >= 32; samples, check_samples >= 1000; margin >= 0; "
                                    "bound > 0; min_coverage in [0, 1]")

    @classmethod
    def from_yaml(cls, **overrides) -> "RigGCSettings":
        """conf/data/animals.yaml's `gcs`, some values replaced by `overrides`."""
        return yaml_settings(cls, "data/animals.yaml", "gcs", **overrides)

    @classmethod
    def from_config(cls, d) -> "RigGCSettings":
        """From `data.gcs` (or some of its keys, None: none; the rest: the YAML's); an unknown
        key is a DataError."""
        return from_group(cls, d, "data/animals.yaml", "gcs", field="data.gcs")


@dataclass
class PosedShape:
    """One posed, closed, normalised mesh with its template GCs and how well they fit.

    gcs: GC dicts in template order (normalised frame); coverage: share of the check samples
    inside the union; purity (G,): share of each GC's own check samples inside it; joints
    (J, 3): the posed joints in the normalised frame; center, scale: normalised = (posed -
    center) * scale; owner (V,): per vertex of `mesh`, the template GC (index) that holds most
    of the skin weight there (what the rig says moves it; a carved GC's part moved to it)."""

    mesh: trimesh.Trimesh
    gcs: list[dict]
    coverage: float
    purity: np.ndarray
    joints: np.ndarray
    center: np.ndarray
    scale: float
    owner: np.ndarray


def joint_depth(rig: Rig) -> np.ndarray:
    """(J,) depth of each skin joint below its topmost ancestor joint."""
    par = rig.joint_parent()
    depth = np.zeros(len(par), dtype=np.int64)
    for j in range(len(par)):
        p = par[j]
        while p >= 0:
            depth[j] += 1
            p = par[p]
    return depth


def gc_of_joint(template: Template, rig: Rig, joint_map=None) -> tuple[np.ndarray, dict]:
    """(J,) template GC index of every joint (-1: claimed by none) and the resolved chains:
    `joint_map`'s (a `skeleton_map.JointMap`) when given, else by the template's joint names.
    DataError when a joint carrying skin weight is claimed by no GC."""
    resolved = joint_map.resolved if joint_map is not None else \
        template.resolve_joints(rig.joint_names, joint_depth(rig), rig.source)
    owner = np.full(len(rig.joints), -1)
    for g, name in enumerate(template.names):
        owner[resolved[name]["skinned"]] = g
    load = np.bincount(rig.skin_joints.ravel(), rig.skin_weights.ravel(), minlength=len(owner))
    free = np.flatnonzero((owner < 0) & (load > 1e-6))
    if len(free):
        j = int(free[np.argmax(load[free])])
        raise DataError(f"joint {rig.joint_names[j]!r} carries skin weight ({load[j]:.1f} "
                        f"vertices' worth) but no GC of template {template.source or template.name} "
                        f"claims it", path=rig.source, field="skinned",
                        fix=f"add {rig.joint_names[j]!r} to the `skinned` joints of the GC whose "
                            "surface it moves")
    return owner, resolved


def _surface_with_owner(V: np.ndarray, F: np.ndarray, weights_gc: np.ndarray, n: int,
                        rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """n points uniform over the mesh (V, 3), (F, 3) and the GC holding most of their weight,
    interpolated barycentrically from the vertices' per-GC weights (V, G)."""
    tri = V[F]
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    face = rng.choice(len(F), size=n, p=area / area.sum())
    r1, r2 = rng.random((2, n))
    s = np.sqrt(r1)
    w = np.stack([1.0 - s, s * (1.0 - r2), s * r2], axis=1)
    pts = np.einsum("nk,nkd->nd", w, tri[face])
    wg = np.einsum("nk,nkg->ng", w, weights_gc[F[face]])
    return pts, wg.argmax(1)


def _bezier_fit(P: np.ndarray, degree: int) -> np.ndarray:
    """Control points (degree+1, 3) of the least-squares Bezier through the polyline P (k, 3)
    (resampled evenly by arc length; ends interpolated)."""
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))]
    s = np.linspace(0.0, 1.0, 64)
    Q = np.stack([np.interp(s * arc[-1], arc, P[:, k]) for k in range(3)], 1)
    B = bernstein_basis(degree, s)
    ctrl = np.empty((degree + 1, 3))
    ctrl[0], ctrl[-1] = Q[0], Q[-1]
    if degree > 1:
        rhs = Q - B[:, :1] * ctrl[0] - B[:, -1:] * ctrl[-1]
        ctrl[1:-1] = np.linalg.lstsq(B[:, 1:-1], rhs, rcond=None)[0]
    return ctrl


def _extended(end: np.ndarray, d: np.ndarray, own: np.ndarray) -> np.ndarray | None:
    """The point past `end` along unit `d` where the part's own samples (M, 3) end, less the
    samples' median distance from the axis (the cap rounds the rest); None if none lie past."""
    rel = own - end
    s = rel @ d
    lat = np.linalg.norm(rel - s[:, None] * d, axis=1)
    ahead = s > 0
    if ahead.sum() < 3:
        return None
    r = float(np.median(lat[ahead]))
    tip = float(s[ahead & (lat <= max(r, 1e-9) * 1.5)].max(initial=0.0))
    return end + d * (tip - r) if tip - r > 1e-3 * max(r, 1e-3) else None


def chain_polyline(chain: np.ndarray, own: np.ndarray, extend: tuple[bool, bool],
                   axis: np.ndarray | None = None) -> np.ndarray:
    """The polyline (k', 3) a GC's curve is fitted through: its chain's posed joints (k, 3),
    extended to the surface at the ends `extend` marks. A one-joint chain runs from the joint
    along `axis` (its bone, (3,)), or without one toward the centroid of its own samples (which
    ears or antlers pull off the head's own direction)."""
    P = np.asarray(chain, np.float64)
    if len(own) == 0:
        return P
    if len(P) == 1:
        d = own.mean(0) - P[0] if axis is None else np.asarray(axis, np.float64).copy()
        if not np.linalg.norm(d) > 1e-9:
            return P
        d /= np.linalg.norm(d)
        tip = _extended(P[0], d, own)
        return np.stack([P[0], tip]) if tip is not None else P
    for side in (1, 0):
        if not extend[side]:
            continue
        end, prev = (P[-1], P[-2]) if side == 1 else (P[0], P[1])
        d = end - prev
        if not np.linalg.norm(d) > 1e-9:
            continue
        tip = _extended(end, d / np.linalg.norm(d), own)
        if tip is not None:
            P = np.vstack([P, tip]) if side == 1 else np.vstack([tip, P])
    return P


def _gc(name, ctrl, up, keys, caps) -> GeneralizedCylinder:
    return GeneralizedCylinder.from_dict({"name": name, "curve": {"type": "bezier",
                                                                  "points": ctrl.tolist()},
                                          "up": [float(x) for x in up], "keys": keys,
                                          "caps": [float(c) for c in caps]})


def template_gc(tgc: TemplateGC, polyline: np.ndarray, own: np.ndarray, margin: float,
                floor: float, where: str | None = None,
                trim: tuple[float, float] = (0.5, OUTLIER)) -> GeneralizedCylinder:
    """The GC of one template entry: Bezier through `polyline`, radii and caps from its own
    surface samples (M, 3) (far outliers of a key window left to coverage repair: those
    farther from the axis than trim[1] x the window's trim[0] quantile)."""
    if len(polyline) < 2 or not np.linalg.norm(polyline[-1] - polyline[0]) > 1e-6:
        raise DataError("its joint chain has no length and no surface past it to extend to",
                        path=where, gc=tgc.name, field="joints",
                        fix="give the GC at least two joints that lie apart")
    ctrl = _bezier_fit(polyline, tgc.degree)
    up = np.asarray(tgc.up, np.float64)
    try:
        unit = _gc(tgc.name, ctrl, up, [{"t": 0.0, "radii": [1.0, 1.0]}], (1.0, 1.0))
    except GeometryError as e:
        raise DataError(f"cannot build its frame at this pose ({e})", path=where, gc=tgc.name,
                        field="up", fix="choose an up vector that is never along the part") from None
    key_t = np.asarray(tgc.keys)
    rel = np.asarray(unit.to_relative(own)) if len(own) else np.zeros((0, 3))
    t = (np.clip(rel[:, 0], -1.0, 1.0) + 1.0) / 2.0
    tube = np.abs(rel[:, 0]) <= 1.0
    radii = np.full((len(key_t), 2), np.nan)
    edges = np.r_[key_t[0], key_t, key_t[-1]]
    r_all = np.hypot(rel[:, 1], rel[:, 2])
    for k, tk in enumerate(key_t):  # radii lerp between keys: hold both adjacent intervals
        lo, hi = edges[k], edges[k + 2]
        sel = tube & (t >= lo - 1e-9) & (t <= hi + 1e-9) if len(key_t) > 1 else tube
        if sel.sum() >= 10:
            sel &= r_all <= trim[1] * np.quantile(r_all[sel], trim[0])
        if sel.sum() >= 3:
            radii[k] = ellipse_radii(rel[sel, 1], rel[sel, 2], floor)
    have = np.flatnonzero(~np.isnan(radii[:, 0]))
    for k in np.flatnonzero(np.isnan(radii[:, 0])):
        radii[k] = radii[have[np.argmin(np.abs(have - k))]] if len(have) else floor
    radii *= 1.0 + margin
    if len(key_t) > 1:
        r_at = np.stack([np.interp(t, key_t, radii[:, j]) for j in range(2)], axis=1)
    else:
        r_at = np.broadcast_to(radii[0], (len(t), 2))
    ab2 = ((rel[:, 1:] / r_at) ** 2).sum(axis=1)
    caps = []
    for end, past, along in ((0, rel[:, 0] < -1.0, -1.0 - rel[:, 0]),
                             (-1, rel[:, 0] > 1.0, rel[:, 0] - 1.0)):
        end_r = float(np.sqrt(np.prod(radii[end])))
        keep = past & (ab2 <= 1.0)  # off-axis samples past an end are left to growth
        if keep.any():
            slack = np.sqrt(np.clip(1.0 - ab2[keep], 0.3, None))
            caps.append(max(float((along[keep] / slack).max()) * (1.0 + margin), 0.25 * end_r))
        else:
            caps.append(0.5 * end_r)
    keys = [{"t": float(tk), "radii": [float(r) for r in rr], "twist": 0.0}
            for tk, rr in zip(key_t, radii)]
    return _gc(tgc.name, ctrl, up, keys, caps)


def carved_polyline(own: np.ndarray, base: np.ndarray, bins: int = 8) -> np.ndarray:
    """The polyline (k, 3) a carved GC's curve is fitted through: from `base` (where the part
    leaves its source) through the centroids of its samples (M, 3) binned by distance from
    `base` (an antler's beam: the tines of a bin average onto it)."""
    d = np.linalg.norm(own - base, axis=1)
    edges = np.quantile(d, np.linspace(0.0, 1.0, bins + 1))
    cents = [own[(d >= lo) & (d <= hi)].mean(0) for lo, hi in zip(edges[1:-1], edges[2:])]
    P = np.vstack([base, *cents])
    keep = np.r_[True, np.linalg.norm(np.diff(P, axis=0), axis=1) > 1e-6]
    return P[keep]


def carve_owner(gcs: dict[int, GeneralizedCylinder], carved: list[tuple[int, int, np.ndarray | None,
                np.ndarray]], points: np.ndarray, owner: np.ndarray) -> np.ndarray:
    """`owner` (N,) with the carved GCs' samples moved to them: a sample owned by a carved GC's
    source `src` that lies farther than CARVE_REACH from the source's core GC gcs[src], on the
    carved GC's side (points - origin) . side > 0 (None: either side)."""
    out = owner.copy()
    for g, src, side, origin in carved:
        sel = np.flatnonzero(owner == src)
        if not len(sel):
            continue
        rho, _ = rho_matrix([gcs[src]], points[sel])
        far = rho[0] > CARVE_REACH
        if side is not None:
            far &= (points[sel] - origin) @ side > 0
        out[sel[far]] = g
    return out


def closed_posed_mesh(V: np.ndarray, F: np.ndarray, resolution: int, seed: int = 0) -> trimesh.Trimesh:
    """The posed mesh (open, several pieces) closed by the proxy: its closed components as one
    watertight mesh."""
    proxy = closed_proxy(V, F, resolution=resolution, seed=seed)
    return trimesh.util.concatenate(proxy.components) if len(proxy.components) > 1 \
        else proxy.components[0]


def template_in_frame(template: Template, joint_map) -> Template:
    """The template with its vectors (GC `up`, carve `side`) turned from its own frame into the
    rig's body frame of `joint_map` (unchanged without a map or when the template has no
    `frame`: its vectors are then taken as written in the rig's frame)."""
    if joint_map is None or template.frame is None:
        return template
    src = np.stack([template.front, np.cross(template.up, template.front), template.up], 1)
    dst = np.stack([joint_map.front, joint_map.left, joint_map.up], 1)
    R = dst @ np.linalg.inv(src)

    def turn(v):
        return tuple(float(x) for x in R @ np.asarray(v, np.float64))

    gcs = tuple(dataclasses.replace(
        g, up=turn(g.up), carve=None if g.carve is None else {
            **g.carve, "side": None if g.carve["side"] is None else turn(g.carve["side"])})
        for g in template.gcs)
    return dataclasses.replace(template, gcs=gcs)


@dataclass
class _Posed:
    """What the GC fits of one pose share: normalised posed vertices, mesh, joints, bone axes,
    skin matrices, surface samples and the GC owning each."""

    V: np.ndarray
    mesh: trimesh.Trimesh
    center: np.ndarray
    scale: float
    joints: np.ndarray
    axes: np.ndarray | None
    skin_m: np.ndarray
    fit_pts: np.ndarray
    owner: np.ndarray
    ref_owner: np.ndarray
    tree: cKDTree


def _posed(rig: Rig, owner_j: np.ndarray, G: int, clip, time, st: RigGCSettings,
           rng: np.random.Generator) -> _Posed:
    """Pose, close and normalise the rig; sample its surface and give every sample the GC that
    holds most of its skin weight."""
    V = rig.posed(clip, time)
    closed = closed_posed_mesh(V, rig.faces, st.resolution, st.seed)
    mesh, center, scale = normalize(closed, st.bound)
    joints = (rig.joint_positions(clip, time) - center) * scale
    axes = rig.bone_axes(clip, time)  # normalising is a similarity: directions unchanged
    wgc = np.zeros((len(V), G))
    cols = owner_j[rig.skin_joints]
    np.add.at(wgc, (np.repeat(np.arange(len(V)), cols.shape[1]), np.clip(cols, 0, None).ravel()),
              (rig.skin_weights * (cols >= 0)).ravel())
    n_ref = max(4 * st.samples, 100_000)
    ref, ref_owner = _surface_with_owner((V - center) * scale, rig.faces, wgc, n_ref, rng)
    tree = cKDTree(ref)
    MV, MF = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    pts, _ = sample_surface(MV, MF, st.samples, rng)
    fit_pts = np.concatenate([MV, pts])
    return _Posed(V=V, mesh=mesh, center=center, scale=float(scale), joints=joints, axes=axes,
                  skin_m=rig.skin_matrices(clip, time)[:, :3, :3], fit_pts=fit_pts,
                  owner=ref_owner[tree.query(fit_pts, k=1)[1]], ref_owner=ref_owner, tree=tree)


def _carved_gcs(template: Template, resolved: dict, ps: _Posed, chain_gc):
    """(carved entries, their source GCs' core GCs, the carved entries present on this rig,
    the samples' owners with the carved parts moved to their GCs)."""
    names = template.names
    carved = []
    for g, tgc in enumerate(template.gcs):
        if tgc.carve is not None:
            src = names.index(tgc.carve["from"])
            j0 = resolved[names[src]]["chain"][0]
            side = None if tgc.carve["side"] is None \
                else ps.skin_m[j0] @ np.asarray(tgc.carve["side"])
            carved.append((g, src, None if side is None else side / np.linalg.norm(side),
                           ps.joints[j0]))
    core = {}
    for src in sorted({c[1] for c in carved}):
        keep = ps.owner == src
        for _ in range(2):  # the first fit still holds the part
            core[src] = chain_gc(src, ps.fit_pts[keep], CORE_TRIM)
            mine = [c for c in carved if c[1] == src]
            keep = carve_owner(core, mine, ps.fit_pts, ps.owner) == src
    carved_owner = carve_owner(core, carved, ps.fit_pts, ps.owner)
    # a part with too few samples is absent on this rig: its samples stay with the source
    present = [c for c in carved if (carved_owner == c[0]).sum() >= CARVE_MIN]
    return carved, core, present, carve_owner(core, present, ps.fit_pts, ps.owner)


def _fit_gcs(template: Template, ps: _Posed, owner, carved, core, present, chain_gc,
             st: RigGCSettings, where) -> list[GeneralizedCylinder]:
    """Every template GC fitted to its own samples, grown alone to hold them, then together to
    cover the surface."""
    floor = 1e-3 * 2.0 * st.bound
    gcs = []
    for g, tgc in enumerate(template.gcs):
        own = ps.fit_pts[owner == g]
        if tgc.carve is None:
            gcs.append(chain_gc(g, own))
            continue
        _, src, side, origin = next(c for c in carved if c[0] == g)
        if any(c[0] == g for c in present):
            rho, _ = rho_matrix([core[src]], own)
            base = own[rho[0] <= np.quantile(rho[0], 0.05)].mean(0)
            poly = carved_polyline(own, base)
        else:  # absent on this rig: a small GC at the source's first joint
            r = float(np.sqrt(np.prod(core[src].to_dict()["keys"][0]["radii"])))
            d = side if side is not None else np.asarray(tgc.up, np.float64) / np.linalg.norm(tgc.up)
            poly, own = np.stack([origin, origin + 0.3 * r * d]), own[:0]
        if len(poly) < 2:
            poly = np.stack([poly[0], poly[0] + 1e-2 * np.asarray(tgc.up, np.float64)])
        gcs.append(template_gc(tgc, poly, own, st.margin, floor, where))
    for g in range(len(gcs)):  # alone: a sample inside another GC must still end up in its own
        own = ps.fit_pts[owner == g]
        rho, _ = rho_matrix([gcs[g]], own)
        reach = np.inf if template.gcs[g].carve is not None else OWN_REACH  # a carved part: all its own
        gcs[g] = grow_to_cover([gcs[g]], own[rho[0] <= reach])[0]
    return grow_to_cover(gcs, ps.fit_pts)


def pose_shape(rig: Rig, template: Template, clip: str | None = None, time: float = 0.0,
               settings: RigGCSettings | None = None, name: str | None = None,
               joint_map=None) -> PosedShape:
    """The rig at `time` of `clip` (None: rest) as a closed normalised mesh with the
    template's GCs; the joints of each GC by `joint_map` (`skeleton_map.JointMap`, whose body
    frame the template's vectors are turned into) or else by the template's joint names.
    DataError (naming the rig, the shape and the numbers) when the GCs cover less than
    `settings.min_coverage` of its surface."""
    st = settings or RigGCSettings.from_yaml()
    where = f"{rig.source}" + (f" [{name}]" if name else "")
    template = template_in_frame(template, joint_map)
    owner_j, resolved = gc_of_joint(template, rig, joint_map)
    G = len(template.gcs)
    ps = _posed(rig, owner_j, G, clip, time, st, np.random.default_rng(st.seed))
    floor = 1e-3 * 2.0 * st.bound

    def chain_gc(g, own, trim=(0.5, OUTLIER)):
        tgc, chain = template.gcs[g], resolved[template.gcs[g].name]["chain"]
        axis = ps.axes[chain[0]] if ps.axes is not None and len(chain) == 1 else None
        poly = chain_polyline(ps.joints[chain], own, tgc.extend, axis)
        return template_gc(tgc, poly, own, st.margin, floor, where, trim)

    carved, core, present, owner = _carved_gcs(template, resolved, ps, chain_gc)
    gcs = _fit_gcs(template, ps, owner, carved, core, present, chain_gc, st, where)
    MV, MF = np.asarray(ps.mesh.vertices), np.asarray(ps.mesh.faces)
    check, _ = sample_surface(MV, MF, st.check_samples, np.random.default_rng([st.seed, 1]))
    check_owner = carve_owner(core, present, check, ps.ref_owner[ps.tree.query(check, k=1)[1]])
    pp, pg, _ = gc_membership(check, gcs)
    coverage = float((np.bincount(pp, minlength=len(check)) > 0).mean())
    own_in = np.zeros(G)
    np.add.at(own_in, pg[check_owner[pp] == pg], 1.0)
    n_own = np.bincount(check_owner, minlength=G)
    purity = np.where(n_own > 0, own_in / np.maximum(n_own, 1), 1.0)
    if coverage < st.min_coverage:
        raise DataError(f"the template GCs cover only {coverage:.5f} of the posed surface "
                        f"(need {st.min_coverage})", path=where, field="gcs",
                        fix="raise data.gcs.samples or data.gcs.margin, or give the uncovered "
                            "part a GC in the template")
    return PosedShape(mesh=ps.mesh, gcs=[rounded_gc_dict(g.to_dict()) for g in gcs],
                      coverage=coverage, purity=purity, joints=ps.joints, center=ps.center,
                      scale=ps.scale, owner=owner[:len(MV)].copy())
