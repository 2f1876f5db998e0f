"""The `next:` hint repeats the recipe's overrides, so the printed command continues it."""
import shlex

from ngc_gen.app.runtime.config import compose_config
from ngc_gen.app.runtime.next_hint import SAMPLE_KEYS, next_command, overrides_used


GIVEN = ["experiment=generate", "data=folder", "data.path=/tmp/my meshes",
         "annotate.template=datasets/animals/quadruped_transfer.yaml", "stage=shape_latent",
         "hydra.run.dir=outputs/sl", "threads=1", "shape_latent.max_steps=50"]


def words(hint: str) -> list[str]:
    return shlex.split(hint)[2:]


def test_the_diffusion_hint_composes_the_same_recipe(tmp_path):
    hint = next_command("train.py", ["stage=diffusion", f"shape_latent_run={tmp_path}"],
                        overrides=GIVEN)
    assert hint.startswith("python train.py ")
    given = words(hint)
    assert "hydra.run.dir=outputs/sl" not in given and "stage=shape_latent" not in given
    now = compose_config("train", [*given, f"run_dir={tmp_path / 'd'}"])
    before = compose_config("train", [o for o in GIVEN if not o.startswith("hydra.")]
                            + [f"run_dir={tmp_path / 's'}"])
    assert now.stage == "diffusion" and now.shape_latent_run == str(tmp_path)
    for key in ("data", "annotate", "diffusion", "prepare", "model", "batch_size", "threads"):
        assert now[key] == before[key], key
    assert now.data.path == "/tmp/my meshes" and now.data.name == "my meshes"


def test_the_sample_hint_keeps_what_sample_py_reads():
    hint = next_command("sample.py", ["run=outputs/d", "mode=generate"], keep=SAMPLE_KEYS,
                        overrides=GIVEN + ["viz.up=y", "extract.resolution=96"])
    assert words(hint) == ["threads=1", "viz.up=y", "extract.resolution=96", "run=outputs/d",
                           "mode=generate"]
    compose_config("sample", words(hint) + ["out_dir=x"])  # sample.py accepts every word


def test_a_pipeline_step_hints_with_its_own_overrides():
    with overrides_used(["experiment=generate", "run_dir=/r/shape_latent",
                         "stage=shape_latent"]):
        hint = next_command("train.py", ["stage=diffusion", "shape_latent_run=/r/shape_latent"])
    assert words(hint) == ["experiment=generate", "stage=diffusion",
                           "shape_latent_run=/r/shape_latent"]
    assert words(next_command("train.py", ["stage=diffusion"])) == ["stage=diffusion"]
