"""Fixtures for edit tests: a real NGCDecoder whose weights are set so its field is a closed,
code-dependent tube in relative coordinates, and a tiny fitting checkpoint holding two shapes."""
from __future__ import annotations

import numpy as np
import pytest
import torch
import yaml

from ngc_gen.geometry import GeneralizedCylinder
from ngc_gen.lit.autodecoder import AutoDecoder

SIZES = dict(code_dim=8, feature_dim=8, g_hidden=16, g_layers=2, h_hidden=16, h_layers=2,
             pe_frequencies=2)
BODY = {"name": "body", "curve": {"type": "bezier", "points": [[-0.5, 0, 0], [0.0, 0, 0.05],
                                                               [0.5, 0, 0]]},
        "up": [0, 0, 1], "keys": [{"t": 0.0, "radii": [0.16, 0.13]},
                                  {"t": 1.0, "radii": [0.13, 0.12], "twist": 20.0}],
        "caps": [0.1, 0.1]}
ARM = {"name": "arm", "curve": {"type": "bezier", "points": [[0.2, 0, 0.05], [0.25, 0.05, 0.3],
                                                              [0.3, 0.0, 0.55]]},
       "up": [1, 0, 0], "keys": [{"t": 0.0, "radii": [0.09, 0.07]},
                                 {"t": 1.0, "radii": [0.06, 0.05]}],
       "caps": [0.05, 0.06]}
TAIL = {"name": "tail", "curve": {"type": "bezier", "points": [[-0.45, 0, 0.02], [-0.7, 0, 0.1],
                                                               [-0.8, 0.0, 0.3]]},
        "up": [0, 1, 0], "keys": [{"t": 0.0, "radii": [0.1, 0.1]},
                                  {"t": 1.0, "radii": [0.07, 0.07]}],
        "caps": [0.04, 0.04]}
GC_DICTS = [BODY, ARM, TAIL]


def tube_decoder_(decoder, feature_scale: float = 0.25, seed: int = 0):
    """Set an NGCDecoder's h (in place) so sdf = phi(0.5 - cos(pi a) - cos(pi b) + w . g(f(t)))
    with phi smooth, increasing and phi(0) = 0: inside the GC a closed rounded tube (|a|, |b| <
    ~2/3) whose thickness varies with the code and t. g and the codes keep their random init."""
    gen = torch.Generator().manual_seed(seed)
    F = decoder.pe.frequencies
    cos_a, cos_b = 3 + 3 * F + F, 3 + 3 * F + 2 * F  # cos(pi a), cos(pi b) in PE
    lin = [m for m in decoder.h if isinstance(m, torch.nn.Linear)]
    big = 10.0  # SiLU(z + 10) ~ z + 10 for |z| < 3: the hidden layers pass unit 0 on
    with torch.no_grad():
        for m in lin:
            m.weight.zero_()
            m.bias.zero_()
        w = lin[0].weight
        w[0, cos_a] = w[0, cos_b] = -1.0
        n_feat = w.shape[1] - decoder.pe.out_dim
        w[0, decoder.pe.out_dim:] = feature_scale * torch.randn(n_feat, generator=gen) \
            / n_feat ** 0.5
        lin[0].bias[0] = 0.5 + big
        for m in lin[1:-1]:
            m.weight[0, 0] = 1.0
        lin[-1].weight[0, 0] = 1.0
        # phi(0) = 0: subtract the pass-through of z = 0
        z = torch.tensor([[0.0]])
        x = torch.nn.functional.silu(z + big)
        for _ in lin[1:-1]:
            x = torch.nn.functional.silu(x)
        lin[-1].bias[0] = -float(x)
    return decoder


def make_module(seed: int = 0, shapes=("one", "two"), gc_dicts=None) -> AutoDecoder:
    """An AutoDecoder with len(shapes) shapes, each of `gc_dicts` (default: the three test GCs),
    and tube weights."""
    gc_dicts = GC_DICTS if gc_dicts is None else gc_dicts
    torch.manual_seed(seed)
    metas, off = [], 0
    for name in shapes:
        ann = {"name": name, "mesh": "unused.ply", "normalize": {"bound": 0.8}, "gcs": gc_dicts}
        metas.append({"name": name, "code_offset": off, "n_codes": len(gc_dicts),
                      "annotation_yaml": yaml.safe_dump(ann, sort_keys=False)})
        off += len(gc_dicts)
    module = AutoDecoder(kind="ngc", decoder=dict(SIZES), n_codes=off, lr=0.0, code_init_std=1.0,
                         meta={"shapes": metas})
    tube_decoder_(module.decoder)
    return module.eval()


def save_checkpoint(module: AutoDecoder, path) -> None:
    """The parts of a Lightning checkpoint that `load_autodecoder` reads."""
    torch.save({"hyper_parameters": dict(module.hparams), "state_dict": module.state_dict()},
               path)


@pytest.fixture(scope="session")
def module() -> AutoDecoder:
    return make_module()


@pytest.fixture
def gcs() -> list[GeneralizedCylinder]:
    return [GeneralizedCylinder.from_dict(d) for d in GC_DICTS]


@pytest.fixture
def ckpt(tmp_path, module):
    path = tmp_path / "run" / "checkpoints" / "last.ckpt"
    path.parent.mkdir(parents=True)
    save_checkpoint(module, path)
    return path


def surface_points(mesh, n: int = 20000, seed: int = 0) -> np.ndarray:
    from ngc_gen.eval import sample_surface

    return sample_surface(mesh, n, seed)[0]
