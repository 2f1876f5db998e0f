"""Pose transfer between bodies, as extra training latents for the diffusion (docs/generation.md,
"Pose transfer").

A rigged collection shows each body (a species) in some poses only; the held-out-clip benchmark
asks for a body in poses the training set shows on other bodies. Pose transfer gives the EDM
every body in every other body's training poses: body A's shape at a pose q that A and B share,
moved as B moves from q to its pose p, GC by GC down the template's parent tree:
- the torso (the root) and everything with it by the similarity that takes B's body points at
  q to those at p (torso control points and the first control point of each child of the root);
- each other GC about its attachment: its start follows the point of its parent it sits at, and
  its curve turns by the smallest rotation taking B's chord at q to B's chord at p;
- what B's curves do beyond that (bending, the attachment sliding) is added, scaled by the
  ratio of A's chord to B's, and log radii, twists and log caps change by B's change.
Where A and B are the same body at q, the transfer returns B's pose p exactly. The free latent
entries (the codes' part) are A's at q. All arrays are batched over shapes (leading N).
"""
from __future__ import annotations

import numpy as np
import torch

from ngc_gen.data.errors import DataError
from ngc_gen.edit.ops import min_rotation

#: which of another body's poses a body is moved to (`diffusion.pose_transfer.poses`)
POSES = ("missing", "all")


def swing(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(N, 3) directions u, v -> (N, 3, 3) the smallest rotations taking u to v (the edit ops'
    `min_rotation`; a reversal turns about an axis normal to u)."""
    u = u / np.linalg.norm(u, axis=-1, keepdims=True)
    v = v / np.linalg.norm(v, axis=-1, keepdims=True)
    normal = np.cross(u, np.eye(3)[np.abs(u).argmin(-1)])
    return min_rotation(u, v, normal / np.linalg.norm(normal, axis=-1, keepdims=True))


def similarity(x: np.ndarray, y: np.ndarray):
    """Least-squares similarity y ~ c R x + t of point sets (N, M, 3) (Umeyama): c (N,),
    R (N, 3, 3), t (N, 3)."""
    mx, my = x.mean(1, keepdims=True), y.mean(1, keepdims=True)
    xc, yc = x - mx, y - my
    u, s, vt = np.linalg.svd(np.swapaxes(yc, 1, 2) @ xc)
    d = np.ones_like(s)
    d[:, 2] = np.sign(np.linalg.det(u @ vt))
    R = u @ (d[:, :, None] * vt)
    c = (s * d).sum(1) / (xc ** 2).sum((1, 2))
    t = my[:, 0] - c[:, None] * np.einsum("nij,nj->ni", R, mx[:, 0])
    return c, R, t


class PoseTransfer:
    """Moves GC parameter vectors (GCTemplate layout, raw) of body A by body B's pose change.
    `parents`: GC name -> its parent's name (None for the one root), as the GC template says."""

    def __init__(self, template, parents: dict):
        self.template = template
        names = template.names
        missing = [n for n in names if n not in parents]
        if missing:
            raise DataError(f"pose transfer: the GC template gives no parent for {missing}",
                            field="diffusion.pose_transfer.template",
                            fix="pass the GC template the shapes were made with")
        roots = [n for n in names if parents[n] is None]
        if len(roots) != 1 or any(parents[n] not in names for n in names if parents[n]):
            raise DataError(f"pose transfer needs one root GC and parents among {names}, got "
                            f"{parents}", field="diffusion.pose_transfer.template")
        self.parents, self.root = dict(parents), roots[0]
        self.order, todo = [self.root], [n for n in names if n != self.root]
        while todo:  # parents first
            ready = [n for n in todo if parents[n] in self.order]
            if not ready:
                raise DataError(f"pose transfer: the GC parents of {todo} form a cycle",
                                field="diffusion.pose_transfer.template")
            self.order += ready
            todo = [n for n in todo if n not in ready]
        self.slice = {(g, f): s for g, f, s in template.fields()}

    def points(self, theta: np.ndarray, gc: str) -> np.ndarray:
        """(N, P) -> (N, degree + 1, 3) control points of GC `gc`."""
        return theta[:, self.slice[(gc, "points")]].reshape(len(theta), -1, 3)

    def body_points(self, theta: np.ndarray) -> np.ndarray:
        """The points the body's overall move is fitted on: the root's control points and the
        start of each GC that grows from it."""
        kids = [n for n in self.order if self.parents[n] == self.root]
        return np.concatenate([self.points(theta, self.root)] +
                              [self.points(theta, k)[:, :1] for k in kids], 1)

    def __call__(self, a_q: np.ndarray, b_q: np.ndarray, b_p: np.ndarray) -> np.ndarray:
        """(N, P) raw parameters of A at q, B at q, B at p -> (N, P): A at p."""
        a_q, b_q, b_p = (np.asarray(x, np.float64) for x in (a_q, b_q, b_p))
        out = a_q.copy()
        c, R, t = similarity(self.body_points(b_q), self.body_points(b_p))

        def move(x):  # the overall similarity, applied to (N, M, 3)
            return c[:, None, None] * x @ np.swapaxes(R, 1, 2) + t[:, None]

        def chord(x):
            return np.linalg.norm(x[:, -1] - x[:, 0], axis=-1)

        def nearest(curve, point):  # (N, M, 3), (N, 3) -> (N,) index of the nearest point
            return ((curve - point[:, None]) ** 2).sum(-1).argmin(1)

        new, turn, rows = {}, {}, np.arange(len(a_q))
        for g in self.order:
            A, Bq, Bp = move(self.points(a_q, g)), move(self.points(b_q, g)), self.points(b_p, g)
            ratio = (chord(A) / np.maximum(chord(Bq), 1e-9))[:, None, None]
            if g == self.root:
                Rg = np.broadcast_to(np.eye(3), (len(A), 3, 3))
                pts = A + (Bp - Bq) * ratio
            else:
                par = self.parents[g]
                Apar, Bqpar = move(self.points(a_q, par)), move(self.points(b_q, par))
                Bppar = self.points(b_p, par)
                ka, kb = nearest(Apar, A[:, 0]), nearest(Bqpar, Bq[:, 0])
                Rp = turn[par]
                slide = (Bp[:, 0] - Bppar[rows, kb]) - np.einsum(
                    "nij,nj->ni", Rp, Bq[:, 0] - Bqpar[rows, kb])
                par_ratio = chord(Apar) / np.maximum(chord(Bqpar), 1e-9)
                anchor = (new[par][rows, ka] + np.einsum("nij,nj->ni", Rp, A[:, 0] - Apar[rows, ka])
                          + slide * par_ratio[:, None])
                Rg = swing(Bq[:, -1] - Bq[:, 0], Bp[:, -1] - Bp[:, 0])
                bend = (Bp - Bp[:, :1]) - (Bq - Bq[:, :1]) @ np.swapaxes(Rg, 1, 2)
                pts = anchor[:, None] + (A - A[:, :1]) @ np.swapaxes(Rg, 1, 2) + bend * ratio
            new[g], turn[g] = pts, Rg
            out[:, self.slice[(g, "points")]] = pts.reshape(len(a_q), -1)
            for f in ("log_radii", "twist", "log_caps"):
                s = self.slice[(g, f)]
                out[:, s] = a_q[:, s] + (b_p[:, s] - b_q[:, s])
        return out


def body_and_pose(names: list[str], bodies: list[str]) -> list[tuple[str, str] | None]:
    """Split shape names `<body>_<pose>` by the longest body that prefixes them (horse_white
    before horse); None for a name no body prefixes."""
    by_len = sorted(bodies, key=len, reverse=True)
    out = []
    for n in names:
        b = next((b for b in by_len if n.startswith(b + "_")), None)
        out.append(None if b is None else (b, n[len(b) + 1:]))
    return out


def transfer_triples(theta: np.ndarray, names: list[str], bodies: list[str], points,
                     poses: str = POSES[0]):
    """Index triples (a_q, b_q, b_p): body A at training pose p of another body B, through the
    pose q both have in training that is nearest B's p (control points `points`, an index array
    into theta). poses="missing": only the poses A has no training shape of (A is already seen
    in its own); "all": every pose of B. Pairs with no pose in common are skipped."""
    if poses not in POSES:
        raise DataError(f"pose transfer: poses must be one of {POSES}, got {poses!r}",
                        field="diffusion.pose_transfer.poses")
    split = body_and_pose(names, bodies)
    index: dict[str, dict[str, int]] = {}
    for i, bp in enumerate(split):
        if bp is not None:
            index.setdefault(bp[0], {})[bp[1]] = i
    if len(index) < 2:
        raise DataError(f"pose transfer needs shapes of two bodies or more; the training shapes' "
                        f"names start with {sorted(index) or 'none'} of {bodies}",
                        field="diffusion.pose_transfer.bodies",
                        fix="list the bodies (species) the shape names start with")
    triples = []
    for A, poses_a in index.items():
        for B, poses_b in index.items():
            shared = [p for p in poses_b if p in poses_a]
            if A == B or not shared:
                continue
            S = theta[[poses_b[p] for p in shared]][:, points]
            P = theta[list(poses_b.values())][:, points]
            q = ((P[:, None] - S[None]) ** 2).sum(-1).argmin(1)
            for (p, ip), k in zip(poses_b.items(), q):
                if poses == "all" or p not in poses_a:
                    triples.append((poses_a[shared[k]], poses_b[shared[k]], ip))
    return np.asarray(triples, dtype=np.int64).reshape(-1, 3)


def pose_transfer_latents(shape_latent, bodies: list[str], parents: dict,
                          poses: str = POSES[0]) -> torch.Tensor:
    """The transferred latents of a shape-latent module (explicit GC entries): GC entries in the
    decoder's std units (held within its bound), free entries A's at q. (T, D) float."""
    sd = shape_latent.shape_decoder
    if not sd.explicit:
        raise DataError("pose transfer needs explicit latents (shape_latent.shape_decoder."
                        "explicit=true, the default)", field="diffusion.pose_transfer")
    pt = PoseTransfer(shape_latent.template, parents)
    theta = shape_latent.target_params.double().cpu().numpy()
    points = np.concatenate([np.arange(s.start, s.stop) for (_, f), s in pt.slice.items()
                             if f == "points"])
    tri = transfer_triples(theta, shape_latent.names, list(bodies), points, poses)
    if not len(tri):  # every body already has every pose the others have
        return torch.zeros(0, shape_latent.latents.weight.shape[1])
    moved = torch.as_tensor(pt(theta[tri[:, 0]], theta[tri[:, 1]], theta[tri[:, 2]]))
    z = sd.gc_part(sd.normalise(moved.to(sd.param_mean))).clamp(-sd.bound, sd.bound)
    free = shape_latent.latents.weight.detach()[torch.as_tensor(tri[:, 0]), sd.n_params:]
    return torch.cat([z.float(), free.float()], 1)
