"""LatentDiffusion: EDM training on a toy latent set, standardisation, EMA, sampling, checkpoints."""
import copy
import warnings

import lightning as L
import pytest
import torch
from torch.utils.data import DataLoader, TensorDataset

from ngc_gen.data.errors import DataError
from ngc_gen.lit.diffusion import LatentDiffusion

DIM, N, STEPS = 8, 512, 300
NET = dict(width=128, depth=3)


def trainer(steps: int) -> L.Trainer:
    return L.Trainer(max_steps=steps, accelerator="cpu", devices=1, logger=False,
                     enable_checkpointing=False, enable_progress_bar=False,
                     enable_model_summary=False)


@pytest.fixture(scope="module")
def toy():
    """A 3-mode mixture in 8-D (mode sd 0.1), then per-dimension scales 0.1..10 and offsets -5..5
    so that only standardisation makes it well conditioned."""
    g = torch.Generator().manual_seed(0)
    modes = torch.randn(3, DIM, generator=g) * 2.0
    k = torch.multinomial(torch.tensor([0.5, 0.3, 0.2]), N, replacement=True, generator=g)
    scale, offset = torch.logspace(-1, 1, DIM), torch.linspace(-5, 5, DIM)
    latents = (modes[k] + 0.1 * torch.randn(N, DIM, generator=g)) * scale + offset
    return dict(latents=latents, modes=modes * scale + offset, scale=scale,
                weights=torch.bincount(k, minlength=3) / N)


@pytest.fixture(scope="module")
def trained(toy, tmp_path_factory):
    L.seed_everything(0, verbose=False)
    module = LatentDiffusion(DIM, denoiser=NET, lr=2e-3, ema_halflife_steps=50)
    untrained = copy.deepcopy(module)
    untrained.fit_standardisation(toy["latents"])
    loader = DataLoader(TensorDataset(toy["latents"]), batch_size=128, shuffle=True,
                        drop_last=True, generator=torch.Generator().manual_seed(0))
    tr = trainer(STEPS)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tr.fit(module, loader)   # no fit_standardisation: taken from the TensorDataset
    ckpt = tmp_path_factory.mktemp("diffusion") / "last.ckpt"
    tr.save_checkpoint(ckpt)
    return dict(module=module, untrained=untrained, ckpt=ckpt)


def test_statistics_come_from_the_training_latents(toy, trained):
    m = trained["module"]
    assert int(m.latent_count) == N
    torch.testing.assert_close(m.latent_mean, toy["latents"].mean(0))
    torch.testing.assert_close(m.latent_std, toy["latents"].std(0))


def test_loss_decreases(toy, trained):
    before = trained["untrained"].evaluate_loss(toy["latents"], seed=1, repeats=4)
    after = trained["module"].evaluate_loss(toy["latents"], seed=1, repeats=4, use_ema=True)
    # at init D = c_skip x, the exact denoiser of N(0, I): the weighted loss is 1 (measured 1.02)
    assert before == pytest.approx(1.0, abs=0.1)
    assert after < 0.6 * before, (before, after)   # measured ~0.35


def test_samples_land_near_the_data_modes(toy, trained):
    m = trained["module"]
    x = m.sample(1000, seed=1)
    assert x.shape == (1000, DIM) and x.dtype == torch.float32
    # distances in mode-sd units of the data: each coordinate deviates ~N(0, 0.1) from its mode
    z, zm = x / toy["scale"], toy["modes"] / toy["scale"]
    d, k = torch.cdist(z, zm).min(1)
    assert float(d.median()) < 0.5     # measured ~0.27 (0.1 * sqrt(8) ideal); modes are > 3 apart
    assert float((d < 1.0).float().mean()) > 0.95
    torch.testing.assert_close(torch.bincount(k, minlength=3) / 1000.0, toy["weights"],
                               atol=0.08, rtol=0)


def test_standardisation_round_trip(toy):
    m = LatentDiffusion(DIM, denoiser=dict(width=16, depth=1))
    with pytest.raises(RuntimeError, match="fit_standardisation"):
        m.sample(2)
    lat = toy["latents"]
    m.fit_standardisation(lat)
    s = m.standardise(lat)
    torch.testing.assert_close(s.mean(0), torch.zeros(DIM), atol=1e-5, rtol=0)
    torch.testing.assert_close(s.std(0), torch.ones(DIM), atol=1e-5, rtol=0)
    torch.testing.assert_close(m.destandardise(s), lat, atol=1e-5, rtol=1e-6)
    # the untrained model denoises N(0, I) exactly, so its samples are N(mean, std^2) per dimension
    x = m.sample(4000, seed=0)
    assert float(((x.mean(0) - lat.mean(0)) / lat.std(0)).abs().max()) < 0.1
    torch.testing.assert_close(x.std(0), lat.std(0), rtol=0.1, atol=0)
    assert set(m.state_dict()) >= {"latent_mean", "latent_std", "latent_count"}


def test_ema_differs_from_live_weights_and_is_used_for_sampling(trained):
    m = LatentDiffusion.from_checkpoint(trained["ckpt"])
    live, ema = dict(m.net.named_parameters()), dict(m.ema.named_parameters())
    assert live.keys() == ema.keys()
    assert max(float((live[k] - ema[k]).detach().abs().max()) for k in live) > 1e-4
    ref = m.sample(64, seed=2)
    assert not torch.equal(ref, m.sample(64, seed=2, use_ema=False))
    with torch.no_grad():
        for p in m.net.parameters():
            p.add_(torch.randn_like(p))
    assert torch.equal(m.sample(64, seed=2), ref)            # the live weights are not used
    with torch.no_grad():
        m.ema.model.out.bias.add_(1.0)
    assert not torch.equal(m.sample(64, seed=2), ref)        # the EMA weights are


def test_ema_schedule_and_update():
    m = LatentDiffusion(4, denoiser=dict(width=8, depth=1), ema_halflife_steps=100, ema_rampup=0.05)
    assert m.ema_beta(10) == pytest.approx(0.25)                  # half-life 0.05 * 10 = 0.5 steps
    assert m.ema_beta(10 ** 6) == pytest.approx(0.5 ** (1 / 100))
    assert LatentDiffusion(4, denoiser=dict(width=8, depth=1), ema_decay=0.9).ema_beta(5) == 0.9
    with torch.no_grad():
        for p in m.net.parameters():
            p.fill_(1.0)
        for p in m.ema.parameters():
            p.fill_(0.0)
    m.update_ema(0.25)
    assert all(torch.allclose(p, torch.full_like(p, 0.75)) for p in m.ema.parameters())
    assert all(not p.requires_grad for p in m.ema.parameters())


def test_checkpoint_round_trip_gives_identical_samples(trained):
    ckpt = torch.load(trained["ckpt"], map_location="cpu", weights_only=True)
    keys = set(ckpt["state_dict"])
    assert {"latent_mean", "latent_std", "ema.model.out.weight", "net.model.out.weight"} <= keys
    m, loaded = trained["module"], LatentDiffusion.from_checkpoint(trained["ckpt"])
    for kw in (dict(seed=3), dict(seed=3, churn=40.0, S_min=0.05, S_max=50.0, steps=32)):
        assert torch.equal(m.sample(100, **kw), loaded.sample(100, **kw))


def test_sampling_is_reproducible_from_the_seed(trained):
    m = trained["module"]
    a = m.sample(50, seed=5)
    assert torch.equal(a, m.sample(50, seed=5))
    assert torch.equal(a, m.sample(50, generator=torch.Generator().manual_seed(5)))
    assert not torch.equal(a, m.sample(50, seed=6))
    c = m.sample(50, seed=5, churn=40.0, S_min=0.05, S_max=50.0)
    assert torch.equal(c, m.sample(50, seed=5, churn=40.0, S_min=0.05, S_max=50.0))
    assert not torch.equal(a, c)
    with pytest.raises(ValueError, match="either"):
        m.sample(2, generator=torch.Generator(), seed=1)


def test_training_without_statistics_says_how_to_fix():
    m = LatentDiffusion(4, denoiser=dict(width=8, depth=1))
    loader = DataLoader([torch.randn(4) for _ in range(8)], batch_size=4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(RuntimeError, match="fit_standardisation"):
            trainer(2).fit(m, loader)


def test_loading_a_wrong_file_is_a_clear_error(tmp_path):
    bad = tmp_path / "x.ckpt"
    torch.save({"hyper_parameters": {"checkpoint_kind": "ngc_gen.autodecoder"}}, bad)
    with pytest.raises(DataError, match="not a diffusion checkpoint"):
        LatentDiffusion.from_checkpoint(bad)
    with pytest.raises(DataError, match="does not exist"):
        LatentDiffusion.from_checkpoint(tmp_path / "missing.ckpt")


@pytest.fixture(scope="module")
def low_rank():
    """64 latents of 20 entries on a 3-D subspace (scales 5, 1, 0.2) plus a 1e-4 tail, with
    per-entry scales and offsets: per-dimension standardisation leaves 17 directions with no
    data, the principal axes find the 3 that hold it."""
    g = torch.Generator().manual_seed(0)
    basis = torch.linalg.qr(torch.randn(20, 3, generator=g))[0]
    coords = torch.randn(64, 3, generator=g) * torch.tensor([5.0, 1.0, 0.2])
    lat = coords @ basis.T + 1e-4 * torch.randn(64, 20, generator=g)
    return lat * torch.logspace(-1, 1, 20) + torch.linspace(-3, 3, 20)


def test_pca_standardisation_keeps_the_axes_that_hold_the_variance(low_rank, tmp_path):
    m = LatentDiffusion(20, denoiser=dict(width=16, depth=1), standardise="pca",
                        pca_variance=0.999)   # the 1e-4 tail holds far less than 0.1%
    assert m.space_dim == 20                  # sized by the data once it is seen
    m.fit_standardisation(low_rank)
    assert m.space_dim == 3 and m.net.model.inp.in_features == 3
    assert m.ema.model.out.out_features == 3
    s = m.standardise(low_rank)
    assert s.shape == (64, 3)
    # coordinates on orthogonal axes, in per-dimension units (not whitened): uncorrelated, and
    # together they hold all the per-dimension variance (20 entries of variance 1) but the tail
    cov = s.T @ s / 63
    torch.testing.assert_close(cov - torch.diag(cov.diagonal()), torch.zeros(3, 3), atol=1e-3,
                               rtol=0)
    assert float(cov.diagonal().sum()) == pytest.approx(20.0, rel=1e-3)
    assert float(cov[0, 0]) > float(cov[1, 1]) > float(cov[2, 2]) > 0.05
    # the kept axes rebuild every latent (what is dropped is the 1e-4 tail)
    err = (m.destandardise(s) - low_rank) / low_rank.std(0)
    assert float(err.abs().max()) < 1e-2
    x = m.sample(8, seed=0)
    assert x.shape == (8, 20)
    # the checkpoint carries the axes and the space size: the same samples after loading
    tr = trainer(2)
    loader = DataLoader(TensorDataset(low_rank), batch_size=32)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tr.fit(m, loader)
    tr.save_checkpoint(tmp_path / "pca.ckpt")
    loaded = LatentDiffusion.from_checkpoint(tmp_path / "pca.ckpt")
    assert loaded.space_dim == 3
    torch.testing.assert_close(loaded.pca_axes, m.pca_axes)
    assert torch.equal(loaded.sample(16, seed=2), m.sample(16, seed=2))


def test_pca_variance_one_keeps_every_direction_with_data(low_rank):
    m = LatentDiffusion(20, denoiser=dict(width=16, depth=1), standardise="pca",
                        pca_variance=1.0)
    m.fit_standardisation(low_rank)
    assert m.space_dim == 20   # the 1e-4 tail is data too (min(N - 1, dims with variance))
    torch.testing.assert_close(m.destandardise(m.standardise(low_rank)), low_rank,
                               atol=1e-4, rtol=1e-5)
    with pytest.raises(ValueError, match="pca_variance"):
        LatentDiffusion(20, standardise="pca", pca_variance=0.0)


def test_pca_complete_nearest_takes_the_dropped_axes_from_the_nearest_training_latent(
        low_rank, tmp_path):
    """pca_complete=nearest: a point on the kept axes gets what the training latent nearest to
    it there holds on the dropped ones, so each training latent comes back whole where the
    mean completion loses its tail; the residuals travel in the checkpoint."""
    kw = dict(denoiser=dict(width=16, depth=1), standardise="pca", pca_variance=0.9)
    mean, near = LatentDiffusion(20, **kw), LatentDiffusion(20, pca_complete="nearest", **kw)
    for m in (mean, near):
        m.fit_standardisation(low_rank)
    assert near.space_dim == mean.space_dim < 3      # the third axis (scale 0.2) is dropped
    assert near.pca_bank.shape == (64, near.space_dim)
    x = near.standardise(low_rank)
    scale = low_rank.std(0)
    lost = float(((mean.destandardise(x) - low_rank) / scale).abs().max())
    kept = float(((near.destandardise(x) - low_rank) / scale).abs().max())
    assert lost > 0.05 and kept < 1e-4
    # off the data: the nearest latent's residual, added to the point's own kept coordinates
    y = x[:5] + 0.01
    d = torch.cdist(y, x)
    want = mean.destandardise(y) + (low_rank - mean.destandardise(x))[d.argmin(1)]
    torch.testing.assert_close(near.destandardise(y), want, atol=1e-4, rtol=1e-5)
    tr = trainer(2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tr.fit(near, DataLoader(TensorDataset(low_rank), batch_size=32))
    tr.save_checkpoint(tmp_path / "near.ckpt")
    loaded = LatentDiffusion.from_checkpoint(tmp_path / "near.ckpt")
    torch.testing.assert_close(loaded.pca_residual, near.pca_residual)
    assert torch.equal(loaded.sample(8, seed=1), near.sample(8, seed=1))
    with pytest.raises(ValueError, match="pca_complete"):
        LatentDiffusion(20, standardise="pca", pca_complete="nearst")


def test_pca_needs_statistics_before_training(low_rank):
    m = LatentDiffusion(20, denoiser=dict(width=8, depth=1), standardise="pca")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(RuntimeError, match="before trainer.fit"):
            trainer(2).fit(m, DataLoader(TensorDataset(low_rank), batch_size=32))
