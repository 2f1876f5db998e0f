"""The fit's union (model.union): checked, recorded in the checkpoint, read back by the shapes;
checkpoints without a record load with the min; the loss weighs rows by their shares."""
import pytest
import torch

from ngc_gen.lit.autodecoder import AutoDecoder, check_union
from ngc_gen.shape import load_shapes
from ngc_gen.shape.load import recorded_union
from tests.edit.conftest import make_module, save_checkpoint


def test_union_is_checked_and_recorded(tmp_path):
    with pytest.raises(ValueError, match="union.kind"):
        check_union({"kind": "max"})
    with pytest.raises(Exception, match="blend width"):
        check_union({"kind": "blend", "width": 1.5})
    module = make_module()
    assert recorded_union(module.hparams)["blend"] == 0.0  # no record: the min
    save_checkpoint(module, tmp_path / "old.ckpt")
    assert {s.blend for s in load_shapes(tmp_path / "old.ckpt").values()} == {0.0}
    module.hparams.union = check_union({"kind": "blend", "width": 0.3, "k": 0.004})
    save_checkpoint(module, tmp_path / "blend.ckpt")
    shapes = load_shapes(tmp_path / "blend.ckpt")
    assert {(s.blend, s.blend_k) for s in shapes.values()} == {(0.3, 0.004)}
    module.hparams.union = {"kind": "min", "width": 0.3}
    assert recorded_union(module.hparams)["blend"] == 0.0


def test_loss_weighs_rows_by_their_shares():
    torch.manual_seed(0)
    m = AutoDecoder(kind="ngc", decoder=dict(code_dim=4, feature_dim=4, g_hidden=8, g_layers=2,
                                             h_hidden=8, h_layers=2, pe_frequencies=1),
                    n_codes=2, lr=0.0, code_reg=0.0, union={"kind": "blend", "width": 0.25})
    m.log_dict = lambda *a, **k: None
    ids = torch.tensor([0, 1, 1])
    coords = torch.rand(3, 3)
    target = torch.zeros(3)
    err = m.sdf(ids, coords).detach().abs()
    share = torch.tensor([1.0, 0.0, 1.0])
    loss = m.training_step((ids, coords, target, share), 0)
    assert loss.item() == pytest.approx(((err[0] + err[2]) / 2).item(), rel=1e-5)
    assert m.training_step((ids, coords, target), 0).item() == pytest.approx(
        err.mean().item(), rel=1e-5)
