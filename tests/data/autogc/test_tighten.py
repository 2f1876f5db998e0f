"""tighten.least_volume: the active-set fit (a few hundred samples, the ones it leaves outside
added) gives the fit over every sample."""
import numpy as np

import ngc_gen.data.autogc.tighten as tighten


def _problem(n=3000, seed=0):
    """Samples of a bumpy tube along t (a wide middle, a narrow end), a few past each cap."""
    rng = np.random.default_rng(seed)
    t = rng.random(n)
    ang = rng.random(n) * 2 * np.pi
    r = (0.3 + 0.2 * np.sin(np.pi * t) + 0.05 * np.cos(7 * t)) * np.sqrt(rng.random(n))
    y, z = 1.3 * r * np.cos(ang), r * np.sin(ang)
    end = (rng.random(n) < 0.5).astype(int)
    past = np.where(rng.random(n) < 0.1, 0.1 * rng.random(n), 0.0)
    t = np.where(past > 0, end.astype(float), t)
    key_t = np.linspace(0, 1, 5)
    radii = np.full((5, 2), 1.0)
    return key_t, radii, np.array([0.5, 0.5]), 2.0, (t, y, z, past, end), np.ones(n)


def _all_at_once(monkeypatch, args):
    with monkeypatch.context() as m:
        m.setattr(tighten, "FIRST_LOWEST", 10 ** 9)
        return tighten.least_volume(*args)


def test_active_set_fit_equals_the_fit_over_every_sample(monkeypatch):
    args = _problem()
    ref_r, ref_c = _all_at_once(monkeypatch, args)
    monkeypatch.setattr(tighten, "FIRST_PER_BIN", 1)   # a first set that leaves samples out
    monkeypatch.setattr(tighten, "FIRST_LOWEST", 1)
    r, c = tighten.least_volume(*args)
    # the same optimum within SLSQP's tolerance (its objective to 1e-6)
    vol = tighten._volume_grad(args[0], args[3], r[:, 0], r[:, 1], c)[0]
    ref = tighten._volume_grad(args[0], args[3], ref_r[:, 0], ref_r[:, 1], ref_c)[0]
    assert abs(vol / ref - 1) < 1e-5
    np.testing.assert_allclose(r, ref_r, rtol=1e-3)
    np.testing.assert_allclose(c, ref_c, rtol=1e-3)
    t, y, z, past, end = args[4]
    ry = np.interp(t, args[0], r[:, 0])
    rz = np.interp(t, args[0], r[:, 1])
    assert np.all((y / ry) ** 2 + (z / rz) ** 2 + (past / c[end]) ** 2 <= 1 + 1e-9)
