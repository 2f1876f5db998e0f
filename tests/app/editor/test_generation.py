"""The editor on a generation run: sample from a seed, A<->B latent interpolation, editing the
decoded GCs, and saving a program on a shape no checkpoint holds (a checkpoint is written
beside it) that edit.py replays to the same mesh.

The generator is tiny and untrained but real: a ShapeLatentModule on the edit tests' three-GC
template whose parameter statistics pin the GCs to the template (two equal targets), with tube
weights, so decoded shapes are closed tubes whose codes depend on the latent; an untrained
LatentDiffusion samples latents."""
import numpy as np
import pytest
import torch

from tests.app.editor import browser
from ngc_gen.app.editor.latent import LatentShapes
from ngc_gen.app.editor.library import ShapeLibrary
from ngc_gen.app.editor.server import EditorServer
from ngc_gen.app.editor.session import EditorSession
from ngc_gen.generate import ShapeGenerator
from ngc_gen.lit.diffusion import LatentDiffusion
from ngc_gen.lit.shape_latent import ShapeLatentModule
from ngc_gen.models.shape_decoder import GCTemplate

from ...edit.conftest import GC_DICTS, SIZES, tube_decoder_
from .conftest import RES, editor_config, mesh_chamfer
from .test_session import replay

pytestmark = pytest.mark.usefixtures("single_thread")


@pytest.fixture(scope="module")
def generator():
    torch.manual_seed(1)  # not the fitted checkpoint's init: another network
    template = GCTemplate.from_gcs(GC_DICTS)
    module = ShapeLatentModule(n_shapes=2, template=template.to_dict(), ngc=dict(SIZES),
                               latent_dim=4, latent_init_std=1.0,
                               meta={"shapes": [{"name": "a"}, {"name": "b"}]})
    module.set_targets(np.stack([template.vector(GC_DICTS)] * 2))
    tube_decoder_(module.ngc)
    diffusion = LatentDiffusion(dim=module.latents.weight.shape[1],  # GC entries + 4 free
                                denoiser={"width": 16, "depth": 1})
    diffusion.fit_standardisation(module.latents.weight.detach())
    return ShapeGenerator(module.eval(), diffusion.eval(), "test")


@pytest.fixture
def latent_session(generator, opened):
    library = ShapeLibrary(dict(opened.library.shapes), opened.library.checkpoint)
    latent = LatentShapes(generator, library)
    latent.training("a")
    session = EditorSession(library, "a", opened.limits, pose_at=opened.pose_at,
                            chunk=opened.chunk)
    return session, latent


def test_sample_and_interpolate_open_editable_shapes(latent_session, generator):
    session, latent = latent_session
    s = latent.sample(7)
    assert s.name == "sample_s7" and s.gc_names == ["body", "arm", "tail"]
    assert torch.equal(s.codes, latent.sample(7).codes)  # a seed is a shape
    assert not torch.equal(s.codes, latent.sample(8).codes)
    a, b = session.library["a"], latent.training("b")
    ends = [latent.interpolate("a", "b", alpha, 0) for alpha in (0.0, 0.5, 1.0)]
    assert torch.allclose(ends[0].codes, a.codes) and torch.allclose(ends[2].codes, b.codes)
    assert not torch.allclose(ends[1].codes, a.codes)
    assert session.open("sample_s7")
    assert session.set_twist("arm", 1, 50.0)  # its GCs edit like a fitted shape's
    assert session.shape.gcs[1].keys[1].twist == pytest.approx(50.0)


def test_a_generated_shape_saves_a_checkpoint_that_replays(latent_session, tmp_path):
    session, latent = latent_session
    latent.sample(3)
    latent.training("b")
    assert session.open("sample_s3")
    assert session.stretch("body", 0.2, 0.8, 1.2)
    assert session.mix("tail", "b", blend="linear")
    out = session.save(tmp_path / "gen.yaml", RES)
    assert out.paths == (tmp_path / "gen.shapes.ckpt", tmp_path / "gen.yaml")
    theirs = replay(tmp_path, tmp_path / "gen.shapes.ckpt", tmp_path / "gen.yaml")
    assert len(theirs.faces) > 100
    assert mesh_chamfer(session.mesh(RES).mesh, theirs) < 1e-8


def test_mixing_across_networks_is_refused(latent_session):
    session, _ = latent_session
    out = session.mix("tail", "two")  # 'two' is the fitted checkpoint's, another network
    assert not out and "another network" in out.message


def test_server_sample_and_lerp_controls(latent_session, checkpoint, tmp_path):
    session, latent = latent_session
    cfg = editor_config(checkpoint, f"editor.port={browser.free_port()}",
                        "editor.preview_resolution=16", "editor.refine_resolution=24")
    server = EditorServer(session, cfg.editor, latent, out_dir=tmp_path)
    try:
        server.seed.value = 11
        server._on_sample(None)  # what the "sample" button runs
        assert session.base.name == "sample_s11" and server.shape_menu.value == "sample_s11"
        assert "sample_s11" in server.mix_shape.options
        server.lerp_b.value = "b"
        server.lerp_alpha.value = 0.5
        server._on_lerp(None)  # what moving the A <-> B slider runs
        assert session.base.name == "lerp_a_b_0.50"
        shown = server.loop.wait_for(session.version, 24, timeout=60)
        assert shown.n_faces > 100
    finally:
        server.stop()
