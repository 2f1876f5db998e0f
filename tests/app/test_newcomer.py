"""What a newcomer met and must not meet again: caches named after the user's
own mesh folder, not after the shipped creatures."""
from ..helpers import compose_config


def test_a_mesh_folder_names_its_caches():
    cfg = compose_config("train", ["experiment=generate", "data=folder", "data.path=/x/cows/"])
    assert cfg.data.name == "cows"
    assert cfg.prepare.cache_dir.endswith("/prepared/cows_gen50k")
    assert compose_config("train", ["data=folder", "data.path=/x/cows"]).prepare.cache_dir \
        .endswith("/prepared/cows")
    # the shipped creatures keep their cache
    assert compose_config("train", ["experiment=generate"]).prepare.cache_dir.endswith(
        "/prepared/creatures_gen50k")


def test_shape_latents_refuse_another_gc_layout_before_preparing(tmp_path, monkeypatch):
    import pytest
    import trimesh
    import yaml

    from ngc_gen.app.stages import prepare_data as prepare_stage
    from ngc_gen.app.stages.registry import run_stage
    from ngc_gen.data.errors import DataError

    from ..conftest import straight_gc

    trimesh.creation.icosphere(subdivisions=2).export(tmp_path / "ball.ply")
    files = []
    for name, gc in (("a", "body"), ("b", "torso")):  # b's GC has another name
        path = tmp_path / f"{name}.yaml"
        path.write_text(yaml.safe_dump({"name": name, "mesh": "ball.ply",
                                        "gcs": [straight_gc(gc, -0.3, 0.3)]}))
        files.append(str(path))

    def prepared(*args, **kwargs):
        raise AssertionError("a mesh was prepared before the layouts were checked")

    monkeypatch.setattr(prepare_stage, "prepare_uncached", prepared)
    cfg = compose_config("train", ["stage=shape_latent", "data=ant", "data.name=two",
                                   f"data.annotations=[{','.join(files)}]",
                                   f"prepare.cache_dir={tmp_path}/cache",
                                   f"run_dir={tmp_path}/run"])
    with pytest.raises(DataError, match=r"shape b: GC 'torso'.*named 'torso', the template "
                                        r"has 'body'"):
        run_stage(cfg)
    assert not (tmp_path / "cache").exists() and not (tmp_path / "run").exists()
