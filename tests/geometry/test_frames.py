"""Rotation-minimising frames (ngc_gen.geometry.frames)."""
from __future__ import annotations

import numpy as np
import torch

from ngc_gen.geometry.curves import BezierCurve
from ngc_gen.geometry.frames import FrameField


def test_frames_do_not_spin_about_a_twisted_curve():
    """A rotation-minimising frame has no angular velocity about the tangent: along a curve with
    torsion (a 3D cubic), dN/ds . B = 0. A frame that merely stays normal to the tangent (a
    reference vector that is not carried along, or reflected the wrong way, then made normal to
    the tangent) spins about it."""
    curve = BezierCurve(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, 1.0, 1.0]]))
    field = FrameField(curve, up=[0.0, 0.0, 1.0])
    s = torch.linspace(0.0, 1.0, 2001, dtype=torch.float64)
    _, d1, _ = curve.evaluate(s)
    T = d1 / torch.linalg.norm(d1, dim=1, keepdim=True)
    N, B = field.frames(s, T, None)
    N, B = N.numpy(), B.numpy()
    ds = np.linalg.norm(np.diff(curve.evaluate(s)[0].numpy(), axis=0), axis=1)
    spin = np.einsum("ij,ij->i", np.diff(N, axis=0), 0.5 * (B[1:] + B[:-1])) / ds
    turn = np.linalg.norm(np.diff(T.numpy(), axis=0), axis=1) / ds   # the curvature, for scale
    assert turn.max() > 1.0                                      # the premise: a curved curve
    assert np.abs(spin).max() < 1e-2 * turn.max()
    assert np.allclose(np.einsum("ij,ij->i", N, T.numpy()), 0.0, atol=1e-12)
