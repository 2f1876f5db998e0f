"""Bad input everywhere, as the entry points report it: every case gives exit code 2, one line
`error: ...` that names what to fix (the edit-op reference below it for an unknown op or field),
no traceback, and writes nothing: no run directory, no partial cache, mesh or checkpoint.

Most cases call the runner through the entry points' own wrapper (`run_job`) in this process;
the ones only an entry point can meet (a config Hydra cannot compose, an unknown stage and the
run directory Hydra made for it) and the `cli_` cases, typed as a user types them, run the real
command: those are checked before torch loads (numbers, resolutions against memory, files,
mesh headers, run kinds, the editor's address and folder)."""
from __future__ import annotations

import errno
import os
import re
import time
from pathlib import Path

import pytest
import torch
import trimesh
import yaml

from ngc_gen.app.runtime.cli import run_job
from ngc_gen.app.stages.train_diffusion import run_diffusion
from ngc_gen.app.stages.edit_shapes import run_edit
from ngc_gen.app.stages.sample import run_sample
from ngc_gen.app.stages.registry import run_stage
from ngc_gen.lit.diffusion import LatentDiffusion
from ngc_gen.lit.shape_latent import ShapeLatentModule

from ..conftest import straight_gc
from ..data.test_prepare import NAN_PLY
from ..edit.conftest import SIZES, make_module, save_checkpoint
from ..helpers import compose_config, run_entry
from .test_config import tiny_template

REFERENCE = "edit ops (* = required field):"


# ---- inputs shared by the cases (outside each case's tmp_path, which must stay clean) ----------
def save_lightning_like(module, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save({"hyper_parameters": dict(module.hparams), "state_dict": module.state_dict(),
                "global_step": 0}, path)
    return path


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    d = tmp_path_factory.mktemp("inputs")
    fit = d / "fit" / "checkpoints" / "last.ckpt"
    fit.parent.mkdir(parents=True)
    save_checkpoint(make_module(), fit)
    # a shape-latent run with 8 free latent entries, and a diffusion run trained on the latents
    # of one with 4 that names it as its shape-latent run: latents of the wrong size
    torch.manual_seed(0)
    sl = ShapeLatentModule(n_shapes=2, template=tiny_template(), ngc=dict(SIZES), latent_dim=8,
                           meta={"shapes": [{"name": "a"}, {"name": "b"}]})
    sl_ckpt = save_lightning_like(sl, d / "sl" / "checkpoints" / "last.ckpt")
    sl4 = ShapeLatentModule(n_shapes=2, template=tiny_template(), ngc=dict(SIZES), latent_dim=4,
                            meta={"shapes": [{"name": "a"}, {"name": "b"}]})
    sl4_ckpt = save_lightning_like(sl4, d / "sl4" / "checkpoints" / "last.ckpt")
    w4, w8 = sl4.latents.weight.shape[1], sl.latents.weight.shape[1]  # + the GC entries
    diff = LatentDiffusion(dim=w4, denoiser={"width": 16, "depth": 1},
                           meta={"shape_latent_checkpoint": str(sl_ckpt)})
    diff.fit_standardisation(torch.randn(5, w4))
    diff_ckpt = save_lightning_like(diff, d / "diff" / "checkpoints" / "last.ckpt")
    latents = d / "sl" / "latents.pt"
    torch.save({"kind": "ngc_gen.shape_latents", "names": ["a", "b"],
                "latents": torch.zeros(2, w8)}, latents)
    truncated = d / "truncated.ckpt"
    truncated.write_bytes(fit.read_bytes()[:2000])
    mesh = d / "ball.ply"
    trimesh.creation.icosphere(subdivisions=2).export(mesh)
    return {"fit": fit, "sl": sl_ckpt, "sl4": sl4_ckpt, "diff": diff_ckpt, "latents": latents,
            "truncated": truncated, "mesh": mesh, "dir": d, "w4": w4, "w8": w8}


# ---- how a case runs -----------------------------------------------------------------------------
def in_process(runner, config: str, overrides: list[str]):
    return ("in_process", runner, config, overrides)


def command(script: str, *args: str):
    return ("command", script, args)


def annotation(root: Path, inputs, gc=None, mesh: str = "shape.ply", text=None) -> Path:
    """An annotation YAML (a dict of one GC, or raw `text`) beside a copy of the test mesh."""
    folder = root / "shape"
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "shape.ply").write_bytes(inputs["mesh"].read_bytes())
    doc = {"name": "shape", "mesh": mesh, "normalize": {"bound": 0.8},
           "gcs": [gc or straight_gc("body", -0.3, 0.3)]}
    path = folder / "shape.yaml"
    path.write_text(text if text is not None else yaml.safe_dump(doc))
    return path


def prepare(source: Path, root: Path, *extra: str):
    """stage=prepare of one annotation file (data=ant's dataset type), or of a folder of meshes
    with automatic GCs (data=folder)."""
    data = ([f"data=folder", f"data.path={source}"] if source.is_dir() else
            ["data=ant", "data.name=bad", f"data.annotations=[{source}]"])
    return in_process(run_stage, "train", [
        "stage=prepare", *data, f"prepare.cache_dir={root}/cache", "prepare.n_samples=2000",
        "prepare.coverage_samples=2000", *extra])


def program(root: Path, inputs, ops=None, text=None, *extra: str):
    path = root / "program.yaml"
    path.write_text(text if text is not None else
                    yaml.safe_dump({"name": "p", "shape": "one", "ops": ops}))
    return in_process(run_edit, "edit", [f"run={inputs['fit']}", f"out_dir={root}/out",
                                         f"program_file={path}", "extract.resolution=16",
                                         *extra])


# ---- the cases: id -> (tmp_path, inputs) -> (how it runs, what the error must say) -------------
def case_missing_mesh(t, i):
    return prepare(annotation(t, i, mesh="gone.ply"), t), r"gone\.ply.*not found.*Fix:"


def case_empty_mesh(t, i):
    path = annotation(t, i, mesh="points.obj")
    (path.parent / "points.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    return prepare(path, t), r"points\.obj.*no triangles.*shape\.yaml.*Fix:"


def case_nan_mesh(t, i):
    path = annotation(t, i, mesh="nan.ply")
    (path.parent / "nan.ply").write_text(NAN_PLY)
    return prepare(path, t), r"nan\.ply.*NaN.*Fix:"


def case_degenerate_mesh(t, i):
    line = t / "meshes" / "line.ply"
    line.parent.mkdir()
    trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]], [[0, 1, 2], [1, 2, 3]],
                    process=False).export(line)  # automatic GC: no annotation beside it
    return prepare(line.parent, t), r"line\.ply.*zero area.*Fix:"


def case_malformed_annotation(t, i):
    return prepare(annotation(t, i, text="name: shape\ngcs: [ {name: a\n"), t), \
        r"shape\.yaml.*malformed YAML"


def case_contradictory_annotation(t, i):  # two GCs of one name
    path = annotation(t, i)
    doc = yaml.safe_load(path.read_text())
    doc["gcs"].append(straight_gc("body", -0.2, 0.2))
    path.write_text(yaml.safe_dump(doc))
    return prepare(path, t), r"shape\.yaml.*body"


def case_negative_radius(t, i):
    path = annotation(t, i, gc=straight_gc("body", -0.3, 0.3, radii=(0.9, -0.2)))
    return prepare(path, t), r"GC 'body'.*radi"


def case_uncovered_mesh(t, i):
    path = annotation(t, i, gc=straight_gc("body", -0.1, 0.1, (0.2, 0.2), (0.1, 0.1)))
    return prepare(path, t), r"GC 'body'.*cover only.*Fix: enlarge"


def case_bad_prepare_setting(t, i):
    return prepare(annotation(t, i), t, "prepare.surface_fraction=1.5"), \
        r"prepare\.surface_fraction.*Fix:"


def case_malformed_shard(t, i):
    return prepare(annotation(t, i), t, "prepare.shard=3/2"), \
        r"prepare\.shard = '3/2'.*Fix: write prepare\.shard=i/n"


def case_cache_dir_is_a_file(t, i):
    (t / "occupied").write_text("a file")
    return prepare(annotation(t, i), t, f"prepare.cache_dir={t}/occupied/cache"), \
        r"prepare\.cache_dir.*is a file, not a folder.*Fix: pass prepare\.cache_dir="


def case_disk_full_during_cache_write(t, i):
    return prepare(annotation(t, i), t), \
        r"cannot write .*cache/shape\.npz: No space left on device.*Fix: free disk space"


def case_missing_mandatory_value(t, i):  # data=folder without data.path
    return in_process(run_stage, "train", ["stage=prepare", "data=folder",
                                           f"prepare.cache_dir={t}/cache"]), \
        r"data\.path.*Fix: pass data\.path="


def case_malformed_trainer_setting(t, i):
    return in_process(run_stage, "train", [
        "stage=fit", f"paths.cache_dir={t}/cache", "trainer.max_steps=lots",
        f"run_dir={t}/run"]), r"trainer\.max_steps = 'lots'.*Fix:"


def case_resume_from_another_stage(t, i):
    return in_process(run_stage, "train", [
        "stage=fit", f"paths.cache_dir={t}/cache", "trainer.max_steps=2",
        f"ckpt_path={i['diff']}", f"run_dir={t}/run", "trainer.enable_progress_bar=false"]), \
        r"is a checkpoint of a `train\.py stage=diffusion` run, not of a `train\.py stage=fit` " \
        r"run.*Fix: pass ckpt_path="


def case_latents_file_for_a_checkpoint(t, i):
    return in_process(run_diffusion, "train", [
        "stage=diffusion", f"shape_latent_run={i['latents']}", f"run_dir={t}/run"]), \
        r"latents\.pt is not a shape-latent checkpoint.*Fix: pass the run directory"


def case_latents_of_the_wrong_size(t, i):
    return in_process(run_sample, "sample", [f"run={i['diff']}", f"out_dir={t}/out"]), \
        rf"diffusion latents have {i['w4']} dims, the shape-latent run .* has {i['w8']}.*Fix:"


def case_sample_a_fit_checkpoint(t, i):
    return in_process(run_sample, "sample", [f"run={i['fit']}", f"out_dir={t}/out"]), \
        r"is a checkpoint of a `train\.py stage=fit` run, not of a `train\.py stage=diffusion` " \
        r"run or a `train\.py stage=shape_latent` run.*Fix:"


def case_sample_zero_shapes(t, i):
    return in_process(run_sample, "sample", [f"run={i['diff']}", f"out_dir={t}/out", "n=0",
                                             f"shape_latent_run={i['sl4']}"]), \
        r"n = 0: must be a whole number >= 1, not 0\. Fix: pass n="


def case_sample_out_dir_not_writable(t, i):
    (t / "occupied").write_text("a file")
    return in_process(run_sample, "sample", [f"run={i['diff']}", f"out_dir={t}/occupied/o"]), \
        r"out_dir.*is a file, not a folder.*Fix: pass out_dir="


def case_edit_truncated_checkpoint(t, i):
    return in_process(run_edit, "edit", [f"run={i['truncated']}", "edit=bent_tail",
                                         f"out_dir={t}/out"]), \
        r"truncated\.ckpt is not a loadable checkpoint.*Fix:"


def case_edit_checkpoint_of_another_stage(t, i):
    return in_process(run_edit, "edit", [f"run={i['diff']}", "edit=bent_tail",
                                         f"out_dir={t}/out"]), \
        r"is a checkpoint of a `train\.py stage=diffusion` run, not of a `train\.py stage=fit` " \
        r"run.*Fix:"


def case_edit_out_dir_not_writable(t, i):
    (t / "occupied").write_text("a file")
    return program(t, i, [{"op": "twist", "gc": "arm", "t": 0.5, "degrees": 10}], None,
                   f"out_dir={t}/occupied/out"), r"out_dir.*is a file, not a folder"


def case_edit_malformed_yaml(t, i):
    return program(t, i, text="name: p\nops: [ {op: twist\n"), \
        r"program .*program\.yaml: malformed YAML at line 3, column 1: expected .*Fix: correct"


def case_edit_unknown_op(t, i):
    return program(t, i, [{"op": "curl", "gc": "arm"}]), \
        r"ops\[0\]: op = 'curl': unknown op; use one of \['bend'"


def case_edit_unknown_field(t, i):
    return program(t, i, [{"op": "scale", "gc": "arm", "t": 0.5, "factor": 2, "fallof": 0.1}]), \
        r"ops\[0\]: edit 'scale' on GC 'arm': unknown field\(s\) \['fallof'\]"


def case_edit_handles_fixed_part_of_a_gc(t, i):
    return program(t, i, [{"op": "handles", "gc": "arm", "at": [0.9, 1.0],
                           "fixed": [{"gc": "body", "at": [0, 0.6]}]}]), \
        r"edit 'handles' on GC 'arm': fixed = \[\{'at': \[0, 0\.6\], 'gc': 'body'\}\]: " \
        r"must be a list of GC names.*" \
        r"Fix: whole GCs stay, e\.g\. fixed: \[thorax\]"


def case_edit_bend_bad_index(t, i):
    return program(t, i, [{"op": "bend", "gc": "arm", "indices": [7],
                           "offsets": [0, 0, 0.1]}]), \
        r"ops\[0\]: edit 'bend' on GC 'arm': indices = \[7\]: unknown control point index"


def case_edit_two_programs(t, i):
    return in_process(run_edit, "edit", [f"run={i['fit']}", "edit=bent_tail",
                                         f"program_file={t}/p.yaml", f"out_dir={t}/out"]), \
        r"give exactly one program.*\(got both\)"


def case_edit_py_rejects_before_torch_loads(t, i):
    path = t / "program.yaml"
    path.write_text(yaml.safe_dump({"name": "p", "ops": [{"op": "bendd", "gc": "tail"}]}))
    return command("edit.py", f"run={i['fit']}", f"program_file={path}", f"out_dir={t}/out"), \
        r"ops\[0\]: op = 'bendd': unknown op"


def case_unknown_stage(t, i):
    return command("train.py", "stage=train"), r"stage = 'train': unknown stage.*Fix: choose one of"


def case_unknown_config_key(t, i):
    return command("train.py", "stage=fit", "trainer.max_stepz=10"), \
        r"unknown config key 'trainer\.max_stepz'.*\+trainer\.max_stepz=<value>"


def case_unknown_group_option(t, i):
    return command("train.py", "stage=fit", "model=huge"), \
        r"Could not find 'model/huge'\. Fix: choose one of model=deepsdf \| deepsdf_small \| " \
        r"paper \| small"


def case_override_syntax(t, i):
    return command("sample.py", "extract.resolution=[64"), \
        r"cannot parse the override .extract\.resolution=\[64.*Fix: write key=value"


# ---- as a user types them: the command line, before torch loads ---------------------------------
def train_cli(t, *args):
    return command("train.py", *args, f"hydra.run.dir={t}/run")


def case_cli_missing_mesh(t, i):
    return train_cli(t, "stage=prepare", "data=ant",
                     f"data.annotations=[{annotation(t, i, mesh='gone.ply')}]",
                     f"prepare.cache_dir={t}/cache"), \
        r"gone\.ply: field 'mesh': mesh file not found \(mesh of .*shape\.yaml\)\. Fix: check"


def case_cli_mesh_without_faces(t, i):
    path = annotation(t, i, mesh="points.ply")
    (path.parent / "points.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
        "property float z\nelement face 0\nproperty list uchar int vertex_indices\n"
        "end_header\n0 0 0\n")
    return train_cli(t, "stage=prepare", "data=ant", f"data.annotations=[{path}]",
                     f"prepare.cache_dir={t}/cache"), \
        r"points\.ply.*no triangles \(its PLY header declares no faces\).*Fix: give a surface"


def case_cli_nan_mesh(t, i):
    path = annotation(t, i, mesh="nan.ply")
    (path.parent / "nan.ply").write_text(NAN_PLY)
    return train_cli(t, "stage=prepare", "data=ant", f"data.annotations=[{path}]",
                     f"prepare.cache_dir={t}/cache"), r"nan\.ply.*1 of 3 vertices are NaN.*Fix:"


def case_cli_folder_mesh_without_faces(t, i):
    (t / "meshes").mkdir()
    (t / "meshes" / "points.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    return train_cli(t, "stage=prepare", "data=folder", f"data.path={t}/meshes",
                     f"prepare.cache_dir={t}/cache"), \
        r"points\.obj.*no triangles.*automatic annotation 'points'.*Fix:"


def case_cli_malformed_annotation(t, i):
    path = annotation(t, i, text="name: shape\ngcs: [ {name: a\n")
    return train_cli(t, "stage=prepare", "data=ant", f"data.annotations=[{path}]"), \
        r"shape\.yaml: malformed YAML at line 3.*Fix: correct the YAML"


def case_cli_annotation_key_twice(t, i):
    path = annotation(t, i, text="name: shape\nmesh: shape.ply\nmesh: other.ply\ngcs: []\n")
    return train_cli(t, "stage=prepare", "data=ant", f"data.annotations=[{path}]"), \
        r"shape\.yaml: malformed YAML.*key 'mesh' appears twice.*Fix: remove or rename"


def case_cli_duplicate_gc_names(t, i):
    path = annotation(t, i)
    doc = yaml.safe_load(path.read_text())
    doc["gcs"].append(straight_gc("body", -0.2, 0.2))
    path.write_text(yaml.safe_dump(doc))
    return train_cli(t, "stage=prepare", "data=ant", f"data.annotations=[{path}]"), \
        r"shape\.yaml: GC 'body'.*appear more than once.*Fix: give every GC a unique name"


def case_cli_max_steps_quoted(t, i):
    return train_cli(t, "stage=fit", "trainer.max_steps='300'"), \
        r"trainer\.max_steps = '300': '300' is quoted text.*Fix: pass trainer\.max_steps=300"


def case_cli_fit_resolution_too_large(t, i):
    return train_cli(t, "stage=fit", "extract.resolution=100000"), \
        r"extract\.resolution = 100000: needs about .* the largest resolution that fits is " \
        r"\d+\. Fix: pass extract\.resolution=\d+ or less"


def case_cli_diffusion_without_its_run(t, i):
    return train_cli(t, "stage=diffusion", f"shape_latent_run={t}/nowhere"), \
        r"shape-latent run .*nowhere does not exist\. Fix: pass the run directory"


def case_cli_diffusion_on_a_fit_run(t, i):
    return train_cli(t, "stage=diffusion", f"shape_latent_run={i['fit']}"), \
        r"last\.ckpt is a checkpoint of a `train\.py stage=fit` run, not of a `train\.py " \
        r"stage=shape_latent` run"


def case_cli_diffusion_pose_transfer_template_missing(t, i):
    return train_cli(t, "stage=diffusion", f"shape_latent_run={i['sl']}",
                     f"diffusion.pose_transfer={{bodies:[a,b],template:{t}/nowhere.yaml}}"), \
        r"diffusion\.pose_transfer\.template = .*nowhere\.yaml': GC template file not found\. " \
        r"Fix: pass the template the shapes were made with"


def case_cli_diffusion_pca_complete_unknown(t, i):
    return train_cli(t, "stage=diffusion", f"shape_latent_run={i['sl']}",
                     "diffusion.pca_complete=nearst"), \
        r"diffusion\.pca_complete = 'nearst': unknown choice\. Fix: choose one of mean, nearest"


def case_pose_transfer_template_of_other_gcs(t, i):
    """The quadruped template for a run whose GCs are not the quadruped's."""
    return in_process(run_diffusion, "train", [
        "stage=diffusion", f"shape_latent_run={i['sl']}", f"run_dir={t}/run",
        "diffusion.pose_transfer={bodies:[a,b],template:datasets/animals/quadruped.yaml}"]), \
        r"pose transfer: the GC template gives no parent for \[.*\].*Fix: pass the GC " \
        r"template the shapes were made with"


def case_cli_sample_n_two(t, i):
    return command("sample.py", f"run={i['diff']}", "n=two", f"out_dir={t}/out"), \
        r"n = 'two': must be a whole number >= 1, not the text 'two'\. Fix: pass n="


def case_cli_sample_n_quoted(t, i):
    return command("sample.py", f"run={i['diff']}", "n='3'", f"out_dir={t}/out"), \
        r"n = '3': '3' is quoted text, not a number\. Fix: pass n=3 \(no quotes\)"


def case_cli_sample_resolution_too_large(t, i):
    return command("sample.py", f"run={i['diff']}", "extract.resolution=100000",
                   f"out_dir={t}/out"), r"extract\.resolution = 100000: .*largest resolution " \
                                        r"that fits is \d+"


def case_cli_sample_without_run(t, i):
    return command("sample.py", f"out_dir={t}/out"), r"no run given\. Fix: pass run=<dir>"


def case_cli_sample_a_fit_run(t, i):
    return command("sample.py", f"run={i['fit'].parent.parent}", f"out_dir={t}/out"), \
        r"is a checkpoint of a `train\.py stage=fit` run, not of a `train\.py stage=diffusion`"


def case_cli_sample_unknown_mode_setting(t, i):
    return command("sample.py", f"run={i['diff']}", "mode=interpolate", "steps=1",
                   f"out_dir={t}/out"), r"steps = 1: must be a whole number >= 2"


def case_cli_sample_missing_gcs_file(t, i):
    return command("sample.py", f"run={i['diff']}", "mode=condition", f"gcs={t}/none.yaml",
                   f"out_dir={t}/out"), r"gcs = '.*none\.yaml': no such file\. Fix: pass gcs="


def case_cli_edit_quoted_degrees(t, i):
    path = t / "program.yaml"
    path.write_text("name: p\nops: [{op: twist, gc: arm, t: 1.0, degrees: '30'}]\n")
    return command("edit.py", f"run={i['fit']}", f"program_file={path}", f"out_dir={t}/out"), \
        r"ops\[0\]: edit 'twist' on GC 'arm': degrees = '30': '30' is quoted text, not a " \
        r"number\. Fix: write 30 without quotes"


def case_cli_edit_resolution_too_large(t, i):
    return command("edit.py", f"run={i['fit']}", "edit=bent_tail", "extract.resolution=100000",
                   f"out_dir={t}/out"), r"extract\.resolution = 100000: .*fits is \d+"


def case_cli_edit_a_diffusion_run(t, i):
    return command("edit.py", f"run={i['diff']}", "edit=bent_tail", f"out_dir={t}/out"), \
        r"is a checkpoint of a `train\.py stage=diffusion` run, not of a `train\.py stage=fit`"


def case_cli_edit_not_a_checkpoint(t, i):
    (t / "notes.ckpt").write_text("my notes")
    return command("edit.py", f"run={t}/notes.ckpt", "edit=bent_tail", f"out_dir={t}/out"), \
        r"notes\.ckpt is not a loadable checkpoint.*Fix: pass run="


def case_cli_edit_crafted_pickle(t, i):
    marker = t / "pwned"  # what the file's code would create if it ran

    class Evil:
        def __reduce__(self):
            return (open, (str(marker), "w"))

    path = i["dir"] / f"evil_{t.name}.ckpt"
    torch.save({"hyper_parameters": {"checkpoint_kind": "ngc_gen.autodecoder"},
                "state_dict": {}, "payload": Evil()}, path)
    return command("edit.py", f"run={path}", "edit=bent_tail", f"out_dir={t}/out"), \
        r"holds pickled Python objects besides tensors.*\((builtins|io)\.open\); it is refused " \
        r"because loading it could run code.*never turn the weights_only protection off"


def case_cli_editor_on_every_address(t, i):
    return command("edit.py", f"run={i['fit']}", "viewer=true", "editor.host=0.0.0.0",
                   f"editor.out_dir={t}/saves"), \
        r"editor\.host = '0\.0\.0\.0': binds the editor to a non-loopback address.*Fix: keep " \
        r"editor\.host=127\.0\.0\.1.*editor\.allow_remote=true"


def case_cli_editor_out_dir_not_writable(t, i):
    (t / "occupied").write_text("a file")
    return command("edit.py", f"run={i['fit']}", "viewer=true",
                   f"editor.out_dir={t}/occupied/saves"), \
        r"editor\.out_dir = .*is a file, not a folder.*Fix: pass editor\.out_dir="


def case_cli_editor_refine_resolution_text(t, i):
    return command("edit.py", f"run={i['fit']}", "viewer=true", "editor.refine_resolution=high",
                   f"editor.out_dir={t}/saves"), \
        r"editor\.refine_resolution = 'high': must be a whole number >= 8"


CASES = {name[len("case_"):]: fn for name, fn in globals().items() if name.startswith("case_")}
HELP = {"edit_unknown_op", "edit_unknown_field", "edit_handles_fixed_part_of_a_gc",
        "edit_py_rejects_before_torch_loads", "cli_edit_quoted_degrees"}


def files_under(root: Path) -> set[Path]:
    """Every file below root (a folder made and left empty is no output)."""
    return {p for p in root.rglob("*") if not p.is_dir()}


def test_the_table_is_long_enough():
    assert len(CASES) >= 40


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_input(case, tmp_path, inputs, capsys, monkeypatch):
    how, match = CASES[case](tmp_path, inputs)
    if case == "disk_full_during_cache_write":
        from ngc_gen.data import prepare as prepare_module

        real = prepare_module.atomic_write

        def full_disk(path, write):  # some bytes reach the temp file, then the disk is full
            def failing(f):
                f.write(b"partial npz")
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            return real(path, failing)

        monkeypatch.setattr(prepare_module, "atomic_write", full_disk)
    before = files_under(tmp_path)
    t0 = time.perf_counter()
    if how[0] == "in_process":
        _, runner, config, overrides = how
        with pytest.raises(SystemExit) as e:
            run_job(runner, compose_config(config, overrides))
        code, err = e.value.code, capsys.readouterr().err
    else:
        _, script, args = how
        r = run_entry(script, *args, cwd=tmp_path, timeout=120)
        code, err = r.returncode, r.stderr
    seconds = time.perf_counter() - t0
    assert code == 2, err
    assert "Traceback" not in err, err
    first, *rest = err.rstrip("\n").split("\n")
    assert first.startswith("error: ") and re.search(match, first), first
    assert (rest[0] == REFERENCE) if case in HELP else not rest, err
    assert files_under(tmp_path) == before, sorted(files_under(tmp_path) - before)
    if how[0] == "command":  # rejected before torch loads: a second or two (bench/cli.py)
        assert seconds < 60, seconds
    assert not (tmp_path / "pwned").exists()  # no code of a crafted checkpoint ran
