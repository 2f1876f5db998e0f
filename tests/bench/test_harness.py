"""bench/_harness.py: the result writer, the machine record and the keyed fit cache."""
from __future__ import annotations

import json
import os
import stat

import pytest

from bench import _harness as h


@pytest.fixture
def umask():
    """Set a umask for one test and restore the old one."""
    old = os.umask(0o022)
    os.umask(old)
    yield lambda m: os.umask(m)
    os.umask(old)


def leftovers(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


def test_a_failed_result_write_keeps_the_old_result_whole(tmp_path, monkeypatch):
    """Bench.write goes through the package's atomic writer: a failure mid-write (a full disk)
    leaves the old result and no temp file."""
    from ngc_gen.data import atomic

    b = h.Bench("x", results=tmp_path)
    b.write({"a": 1})

    def broken_fsync(*args):
        raise OSError(28, "No space left on device")   # mid-write: bytes written, not synced

    monkeypatch.setattr(atomic.os, "fsync", broken_fsync)
    with pytest.raises(OSError):
        b.write({"a": 2, "longer": "x" * 1000})
    assert json.loads((tmp_path / "x.json").read_text())["a"] == 1
    assert leftovers(tmp_path) == []


def test_bench_write_refuses_a_result_that_is_not_json_and_keeps_the_old_one(tmp_path):
    b = h.Bench("x", results=tmp_path)
    b.write({"a": 1})
    with pytest.raises((TypeError, ValueError)):
        b.write({"a": object()})
    with pytest.raises(ValueError):
        b.write({"a": float("nan")})
    assert json.loads((tmp_path / "x.json").read_text())["a"] == 1
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("mask,mode", [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_a_result_file_mode_follows_the_umask(tmp_path, umask, mask, mode):
    """Results are readable by the group and others under the usual umask (0644), not
    mkstemp's 0600."""
    umask(mask)
    out = h.Bench("r", results=tmp_path).write({})
    assert stat.S_IMODE(out.stat().st_mode) == mode


def test_every_result_carries_the_same_machine_record(tmp_path):
    b = h.Bench("demo", results=tmp_path)
    path = b.write({"wall_s": 1.0}, commit="abc", torch_threads=1)
    res = json.loads(path.read_text())
    assert path == tmp_path / "demo.json" and res["wall_s"] == 1.0
    m = res["machine"]
    assert tuple(m) == h.MACHINE_KEYS
    assert m["commit"] == "abc" and m["torch_threads"] == 1 and m["cpus"] == os.cpu_count()
    assert m["date_utc"].endswith("Z") and m["date_utc"] == b.date_utc
    assert isinstance(m["load_1min_before"], float) and isinstance(m["load_1min_after"], float)
    with pytest.raises(KeyError):
        b.write({}, load_avg_start=[1, 2, 3])          # not a machine key
    with pytest.raises(ValueError):
        b.write({"machine": {}})                        # the harness writes it


def test_the_harness_imports_with_the_standard_library_only():
    """bench/demo.py runs it under a bare python3: no torch, numpy or omegaconf at import."""
    import subprocess
    import sys

    code = ("import sys, bench._harness; "
            "bad = {'torch', 'numpy', 'omegaconf'} & set(sys.modules); assert not bad, bad")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=h.ROOT)


def counting_fit(calls):
    def fit(run_dir):
        calls.append(run_dir)
        (run_dir / "checkpoint").write_text("weights")
        return {"checkpoint": str(run_dir / "checkpoint"), "train_s": 1.5}
    return fit


def test_fit_cache_reuses_a_matching_recipe_and_refits_a_changed_one(tmp_path):
    cache = h.FitCache("editor", root=tmp_path)
    calls = []
    recipe = {"config": {"trainer": {"max_steps": 1500}, "seed": 0}, "data": {"ant": "aa"}}
    a = cache.get(recipe, counting_fit(calls))
    assert not a.reused and len(calls) == 1 and a.info["train_s"] == 1.5
    same = json.loads(json.dumps(recipe))             # an equal recipe built anew
    b = cache.get(same, counting_fit(calls))
    assert b.reused and len(calls) == 1 and b.run_dir == a.run_dir
    # the editor's old bug: a fit with other steps was reused. Any change refits, elsewhere.
    for changed in ({**recipe, "config": {"trainer": {"max_steps": 300}, "seed": 0}},
                    {**recipe, "config": {"trainer": {"max_steps": 1500}, "seed": 1}},
                    {**recipe, "data": {"ant": "ab"}}):
        c = cache.get(changed, counting_fit(calls))
        assert not c.reused and c.run_dir != a.run_dir
    assert len(calls) == 4
    assert cache.get(recipe, counting_fit(calls)).reused and len(calls) == 4
    assert not cache.get(recipe, counting_fit(calls), refit=True).reused and len(calls) == 5
    assert len(cache.entries()) == 4


def test_fit_cache_refits_when_the_data_bytes_change(tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    (data / "ant.yaml").write_text("gcs: [leg]\n")
    cache, calls = h.FitCache("deform", root=tmp_path / "fits"), []
    key = lambda: {"steps": 10, "data": h.file_identity([data, data / "ant.yaml"])}  # noqa: E731
    cache.get(key(), counting_fit(calls))
    assert cache.get(key(), counting_fit(calls)).reused
    (data / "ant.yaml").write_text("gcs: [leg, tail]\n")     # a re-done annotation
    assert not cache.get(key(), counting_fit(calls)).reused and len(calls) == 2
    with pytest.raises(FileNotFoundError):
        h.file_identity([data / "missing.yaml"])


def test_an_interrupted_fit_is_not_reused(tmp_path):
    cache, calls = h.FitCache("x", root=tmp_path), []

    def dies(run_dir):
        (run_dir / "half.ckpt").write_text("partial")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        cache.get({"a": 1}, dies)
    f = cache.get({"a": 1}, counting_fit(calls))
    assert not f.reused and len(calls) == 1 and not (f.run_dir / "half.ckpt").exists()


def test_recipe_keys_ignore_key_order_and_the_checkout_location():
    a = {"x": 1, "p": str(h.ROOT / "datasets/ant/ant.yaml")}
    b = {"p": "<repo>/datasets/ant/ant.yaml", "x": 1}
    assert h.recipe_key(a) == h.recipe_key(b)
    assert h.recipe_key(a) != h.recipe_key({**a, "x": 2})
    with pytest.raises(TypeError):
        h.recipe_key({"x": object()})


def test_link_latest_points_a_fixed_name_at_the_latest_fit(tmp_path, capsys):
    a, b = tmp_path / "fits/a", tmp_path / "fits/b"
    a.mkdir(parents=True)
    b.mkdir()
    link = tmp_path / "runs/generate/diffusion"
    assert h.link_latest(link, a) and link.resolve() == a.resolve()
    assert h.link_latest(link, b) and link.resolve() == b.resolve()   # repointed in place
    real = tmp_path / "runs/generate/shape_latent"
    real.mkdir()
    assert not h.link_latest(real, a) and real.is_dir() and not real.is_symlink()


def test_a_setting_at_its_neutral_value_leaves_the_recipe_key_as_it_was():
    """Adding a setting (junction_weight, prepare.pair_margin) at the value that does what the
    code did before must not invalidate every cached fit; any other value changes the key."""
    from ngc_gen.app.runtime.config import compose_config

    cfg = compose_config(overrides=["stage=fit", "data=ant"])
    recipe = h.config_recipe(cfg)
    assert "junction_weight" not in recipe and "pair_margin" not in recipe["prepare"]
    assert recipe["prepare"]["n_samples"] == cfg.prepare.n_samples   # the rest stays
    plain = h.config_recipe(compose_config(overrides=["stage=fit", "data=ant",
                                                      "prepare.shell_fraction=0"]))
    assert "shell_fraction" not in plain["prepare"] and "shell_width" not in plain["prepare"]
    for over in ("junction_weight=2", "prepare.pair_margin=0.1", "prepare.shell_fraction=0"):
        other = h.config_recipe(compose_config(overrides=["stage=fit", "data=ant", over]))
        assert h.recipe_key(other) != h.recipe_key(recipe), over


def test_a_bench_reads_another_benchs_fit_from_the_cache(tmp_path):
    """latest_fit: the newest complete fit of the other bench with the asked config values;
    none: one line naming the make target that trains it."""
    cache = h.FitCache("deform", root=tmp_path)
    for steps, seed in ((1500, 0), (300, 0), (1500, 1)):
        cache.get({"config": {"trainer": {"max_steps": steps}, "seed": seed}},
                  counting_fit([]))
    got = h.latest_fit("deform", {"trainer.max_steps": 1500}, root=tmp_path)
    assert got.recipe["config"] == {"trainer": {"max_steps": 1500}, "seed": 1}
    assert h.latest_fit("deform", {"trainer.max_steps": 300}, root=tmp_path).reused
    with pytest.raises(SystemExit, match="run `make bench-deform` first"):
        h.latest_fit("deform", {"trainer.max_steps": 99}, root=tmp_path)
    with pytest.raises(SystemExit, match="make bench-sparse-settings"):
        h.latest_fit("sparse_settings", root=tmp_path)


def test_a_cached_stage_is_keyed_by_its_config_less_the_groups_it_never_reads(tmp_path,
                                                                             monkeypatch):
    from omegaconf import OmegaConf

    monkeypatch.setattr(h, "dataset_identity", lambda cfg: {"shapes": "same"})
    cache, runs = h.FitCache("generate", root=tmp_path / "fits"), []

    def stage(cfg):
        runs.append(cfg.run_dir)

    cfg = lambda lr: OmegaConf.create({"run_dir": None, "model": {"w": 1},  # noqa: E731
                                       "diffusion": {"lr": lr}})
    first = h.cached_stage(cache, "shape_latent", cfg(1e-3), stage, link=tmp_path / "runs/sl",
                           leave_out=("diffusion",))
    again = h.cached_stage(cache, "shape_latent", cfg(5e-4), stage, link=tmp_path / "runs/sl",
                           leave_out=("diffusion",))
    assert not first.reused and again.reused and len(runs) == 1
    assert (tmp_path / "runs/sl").resolve() == first.run_dir.resolve()
    other = h.cached_stage(cache, "shape_latent", cfg(5e-4), stage)   # diffusion read now
    assert not other.reused and len(runs) == 2 and first.info["label"] == "shape_latent"
