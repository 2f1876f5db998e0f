"""What a newcomer met (issue 31, item 8) and must not meet again: caches named after the user's
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
