"""bench/seams.py: an edited shape is judged against the truth moved by the same edit and that
moved truth's own ceiling; both recipes train with the same loss (it does not see the union),
`before` on samples without outer shells; the issue's bar per fit."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from bench import seams
from bench._seams_close import edit_record, edited_truth
from ngc_gen.geometry import GeneralizedCylinder


def gc(p0, p1, radius=0.3, name="gc"):
    return GeneralizedCylinder.from_dict({
        "name": name, "curve": {"type": "bezier", "points": [list(p0), list(p1)]},
        "keys": [{"t": 0.0, "radii": [radius, radius]}], "caps": [0.2, 0.2]})


def test_the_edited_truth_moves_with_the_gcs():
    truth = trimesh.creation.capsule(height=0.8, radius=0.15, count=[12, 12])
    truth.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    gcs = [gc((-0.4, 0, 0), (0.0, 0, 0), name="a"), gc((0.0, 0, 0), (0.4, 0, 0), name="b")]
    same = edited_truth(truth, gcs, gcs)
    assert np.allclose(same.vertices, truth.vertices, atol=1e-5)   # no edit: no motion
    shift = np.array([0.1, -0.2, 0.05])
    moved = [gc(np.add(g.to_dict()["curve"]["points"][0], shift),
                np.add(g.to_dict()["curve"]["points"][1], shift), name=g.name) for g in gcs]
    out = edited_truth(truth, gcs, moved)
    assert np.allclose(out.vertices, truth.vertices + shift, atol=1e-5)  # rigid: rigid
    assert np.array_equal(out.faces, truth.faces)


def test_an_edit_is_judged_by_its_excess_over_the_edited_ceiling():
    base = {"junction_ratio_dist": 1.2, "junction_ratio_normal": 1.5,
            "excess_dist": 1.0, "excess_normal": 1.0}
    # the edit made the junctions' raw ratios worse by 30%, but so did the edited truth's own
    # ceiling: the fit keeps its seams
    m = {"junction_ratio_dist": 1.56, "junction_ratio_normal": 1.5, "extra_pieces": 0}
    ceil = {"junction_ratio_dist": 1.56, "junction_ratio_normal": 1.5}
    rec = edit_record("ant", "after", "p", m, ceil, base)
    assert rec["change_dist"] == pytest.approx(0.0)
    assert rec["ratio_change_dist"] == pytest.approx(0.3)
    worse = edit_record("ant", "after", "p", {**m, "junction_ratio_normal": 1.8}, ceil, base)
    assert worse["excess_normal"] == pytest.approx(1.2)
    assert worse["change_normal"] == pytest.approx(0.2)
    assert "excess" in seams.edit_line(worse) and "+20.0%" in seams.edit_line(worse)


def test_both_recipes_train_with_the_same_loss():
    """`after` (the default: the blend, outer-shell samples) and `before` (the min on uniform
    volume samples, the baseline) differ in the union the fit stage meshes with and in the
    samples; the loss weighs no row by a blend share, so a step costs the same."""
    from ngc_gen.app.runtime.config import compose_config
    from ngc_gen.app.stages.fit import union_blend

    cfgs = {r: compose_config(overrides=["stage=fit", *seams.FIT[r]]) for r in seams.RECIPES}
    assert cfgs["after"].model.union.kind == "blend" and cfgs["before"].model.union.kind == "min"
    assert {union_blend(c) for c in cfgs.values()} == {0.0}
    a, b = (dict(c.model) for c in cfgs.values())
    a.pop("union"), b.pop("union")
    assert a == b
    assert cfgs["before"].prepare.shell_fraction == 0.0 < cfgs["after"].prepare.shell_fraction


def test_the_bar_needs_every_target():
    row = {"excess_dist": 1.1, "excess_normal": 1.15, "extra_pieces": 0, "nc": 0.95,
           "ceiling_nc": 0.97, "fscore": 0.94, "ceiling_fscore": 0.945}
    assert seams.meets_targets(row)          # F 0.94 >= 0.945 - 0.01
    assert not seams.meets_targets({**row, "extra_pieces": 1})
    assert not seams.meets_targets({**row, "excess_normal": 1.16})
    assert not seams.meets_targets({**row, "nc": 0.949})
    assert not seams.meets_targets({**row, "excess_dist": None})


def test_the_step_time_ratio_pairs_each_shapes_two_fits():
    rows = [{"name": "a", "recipe": "before", "step_s": 0.2},
            {"name": "a", "recipe": "after", "step_s": 0.25},
            {"name": "b", "recipe": "before", "step_s": 0.3},
            {"name": "b", "recipe": "after", "step_s": 0.3},
            {"name": "c", "recipe": "before", "step_s": 9.0}]      # no after: left out
    assert seams.step_ratio(rows) == pytest.approx(0.55 / 0.5)
    assert seams.step_ratio(rows[-1:]) is None


def test_a_row_carries_the_local_and_net_figures_beside_its_ceiling(tmp_path):
    """A fit's row holds its local ratios over the ceiling's (the excess against the parts
    that meet) and the net ratio: the fit's error beyond the grid's, junctions over elsewhere
    (the grid's own error taken out of both means)."""
    import json

    fit = {"junction_ratio_dist": 1.0, "junction_ratio_normal": 1.1,
           "junction_ratio_dist_local": 1.05, "junction_ratio_normal_local": 1.2,
           "junction_dist": 2.0, "elsewhere_dist": 2.2, "junction_normal_deg": 10.0,
           "elsewhere_normal_deg": 9.0, "extra_pieces": 0, "normal_consistency": 0.97,
           "fscore": 0.99}
    (tmp_path / "metrics.json").write_text(json.dumps(
        {"shapes": {"deer": fit}, "train_s": 10.0, "steps": 100}))
    ceil = {"junction_ratio_dist": 0.8, "junction_ratio_normal": 0.8,
            "junction_ratio_dist_local": 0.95, "junction_ratio_normal_local": 1.0,
            "junction_dist": 0.2, "elsewhere_dist": 0.2, "junction_normal_deg": 3.0,
            "elsewhere_normal_deg": 4.0, "nc": 0.99, "fscore": 1.0}
    r = seams.row("deer", "after", tmp_path, ceil)
    assert r["excess_dist"] == pytest.approx(1.25)
    assert r["excess_local_dist"] == pytest.approx(1.05 / 0.95)
    assert r["excess_local_normal"] == pytest.approx(1.2)
    assert r["net_ratio_dist"] == pytest.approx(1.8 / 2.0)
    assert r["net_ratio_normal"] == pytest.approx(7.0 / 5.0)
    assert seams.net_ratio(fit, {}, "dist") is None       # an old ceiling without the means
    assert "1.11 / 1.20" in "\n".join(seams.rows_table([{**r, "same_network": True}]))


def test_the_side_by_side_step_time_counts_every_step_after_the_warm_up():
    """The same-run timing leaves out each run's warm-up and pools a recipe's runs over the
    whole timed span, so a slow step (an epoch's end, a checkpoint) counts as in a fit."""
    ends = {"before": [[0.0, 5.0, 5.2, 5.4, 5.6], [0.0, 5.0, 5.2, 5.4, 6.2]],
            "after": [[0.0, 5.0, 5.3, 5.6, 5.9], [0.0, 5.0, 5.3, 5.6, 5.9]]}
    out = seams.step_seconds(ends, warmup=1)
    assert out["step_s"] == {"before": pytest.approx(1.8 / 6), "after": pytest.approx(0.3)}
    assert out["ratio"] == pytest.approx(0.3 / 0.3)


def test_the_table_reports_the_same_run_timing_beside_the_fits_own(monkeypatch):
    res = {"shapes": [{"name": "a", "recipe": "before", "step_s": 0.2},
                      {"name": "a", "recipe": "after", "step_s": 0.4}],
           "steps": 1500, "resolution": 256, "minutes": 1.0,
           "step_time": {"shape": "a", "repeats": 2, "steps": 120, "ratio": 1.02,
                         "step_s": {"before": 0.25, "after": 0.255}}}
    monkeypatch.setattr(seams, "rows_table", lambda rows: [])   # the rows are tested above
    text = seams.table(res)
    assert "after / before 1.020" in text and "2.000" in text
