"""Stage `shape_latent`: one latent per training shape -> template GC parameters + NGC codes.

    python train.py stage=shape_latent data=creatures [data.n=64 data.limit=...]

Prepares the shapes (cached samples with relative coordinates from the annotated GCs), checks
they share one GC template, trains `ShapeLatentModule` with Lightning and writes to the run
directory: checkpoints/ (last.ckpt, best.ckpt), latents.pt ({names, latents (N, D)}),
metrics.json (final losses, decoded-parameter errors, train time), config.yaml, logs/ and, if
`shape_latent.preview` > 0, meshes/<shape>.ply of the first shapes decoded from their latents.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import torch
import yaml
from omegaconf import DictConfig, open_dict

from ngc_gen import workspace
from ngc_gen.data.atomic import atomic_write, atomic_write_text
from ngc_gen.data.body_frame import collection_frame
from ngc_gen.data.errors import DataError
from ngc_gen.data.prepare import PreparedShape

from ..runtime.config import sparse_settings
from ..runtime.config import instantiate_group
from ..runtime.next_hint import next_command
from ..runtime.training import start_run, train

LATENTS_KIND = "ngc_gen.shape_latents"
# settings of the `shape_latent` group the stage reads itself (not ShapeLatentModule arguments)
RUNNER_KEYS = ("init_decoder", "max_steps", "preview", "preview_resolution")


def with_stage_steps(cfg: DictConfig, group: str) -> DictConfig:
    """A copy of cfg whose trainer.max_steps is `<group>.max_steps` when that is set."""
    cfg = cfg.copy()
    steps = cfg[group].get("max_steps")
    if steps is not None:
        with open_dict(cfg):
            cfg.trainer.max_steps = int(steps)
    return cfg


def template_and_targets(prepared: list[PreparedShape]):
    """(GCTemplate of the first shape, annotated parameter vectors (N, P)); DataError naming the
    shape if any shape does not follow the first one's template."""
    from ngc_gen.models.shape_decoder import GCTemplate

    if not prepared:
        raise DataError("the dataset has no shapes", fix="check data.n / data.limit / data.split")
    gcs = [yaml.safe_load(s.annotation_yaml)["gcs"] for s in prepared]
    template = GCTemplate.from_gcs(gcs[0], where=f"shape {prepared[0].name}")
    vectors = np.stack([template.vector(g, where=f"shape {s.name}")
                        for g, s in zip(gcs, prepared)])
    return template, vectors


def check_layouts(annotations) -> dict | None:
    """Every shape has the first one's GC layout (names in order, curve degrees, up vectors,
    key t's) and all share one body frame: checked on the annotations, before any mesh is
    prepared, so a folder whose GCs differ fails in seconds, not after preparing every mesh.
    Returns the collection's frame {up, front} (None: no shape records one); DataError naming
    the shape."""
    from ngc_gen.models.shape_decoder import GCTemplate

    if not annotations:
        return None
    frame = collection_frame([(a.name, a.frame) for a in annotations])
    dicts = [[g.to_dict() for g in a.gcs] for a in annotations]
    template = GCTemplate.from_gcs(dicts[0], where=f"shape {annotations[0].name}")
    for d, a in zip(dicts[1:], annotations[1:]):
        template.check(d, where=f"shape {a.name}")
    return frame


def build_module(cfg: DictConfig, template, vectors, prepared: list[PreparedShape],
                 frame: dict | None = None):
    """The `shape_latent` group's ShapeLatentModule (`_target_`; its NGC decoder is the `model`
    group's), with the annotated parameter vectors as targets; `frame`, the collection's body
    frame, goes into its meta (every sample, picture and edit of the model reads it there)."""
    from .fit import model_kind

    if model_kind(cfg) != "ngc":
        raise DataError(f"stage shape_latent needs an NGC decoder, model is {model_kind(cfg)!r}",
                        field="model", fix="use model=small or model=paper")
    meta = {"dataset": str(cfg.data.name),
            "shapes": [{"name": s.name, "annotation_yaml": s.annotation_yaml} for s in prepared],
            "frame": frame}
    module = instantiate_group(cfg.shape_latent, RUNNER_KEYS, n_shapes=len(prepared),
                               template=template.to_dict(), meta=meta)
    module.set_targets(vectors)
    if cfg.shape_latent.get("init_decoder"):
        init_ngc_from_fit(module, cfg.shape_latent.init_decoder)
    return module


def init_ngc_from_fit(module, path) -> None:
    """Start the NGC decoder from a `stage=fit` run (directory or checkpoint) with the same
    decoder sizes."""
    from ngc_gen.lit.checkpoint import FIT_FIX, load_autodecoder, resolve_checkpoint

    path = resolve_checkpoint(path, FIT_FIX, "fit run")
    fit = load_autodecoder(path)
    if fit.hparams.kind != "ngc" or dict(fit.decoder.config) != dict(module.ngc.config):
        raise DataError(f"{path}: its decoder ({fit.hparams.kind}, {fit.decoder.config}) differs "
                        f"from this run's NGC decoder ({module.ngc.config})",
                        field="shape_latent.init_decoder",
                        fix="fit with the same model preset, or leave init_decoder null")
    module.ngc.load_state_dict(fit.decoder.state_dict())


def save_latents(path: Path, module, checkpoint: Path) -> None:
    """latents.pt: {kind, names, latents (N, D) float32, checkpoint} (torch.load weights_only)."""
    payload = {"kind": LATENTS_KIND, "names": module.names,
               "latents": module.latents.weight.detach().cpu().float().clone(),
               "checkpoint": str(Path(checkpoint).resolve())}
    atomic_write(path, lambda f: torch.save(payload, f))


@torch.no_grad()
def evaluate(module, dm, batches: int = 20) -> dict:
    """Mean losses over the first `batches` batches of a fixed permutation, and readable errors of
    the decoded GC parameters against the annotated ones."""
    from ngc_gen.models.shape_decoder import param_errors

    module.eval()
    ds = dm.train_set
    ds.set_epoch(10 ** 6)  # a permutation no training epoch used
    rows = [module.losses(*ds[i]) for i in range(min(batches, len(ds)))]
    out = {k: float(np.mean([float(r[k]) for r in rows])) for k in rows[0]}
    theta, _ = module.decode(module.latents.weight)
    out["params"] = param_errors(module.template, theta.cpu().numpy(),
                                 module.target_params.cpu().numpy())
    return out


def preview(module, run_dir: Path, n: int, resolution: int, settings=None) -> list[str]:
    """Meshes of the first n training shapes decoded from their latents (decoded GCs + codes);
    settings: the sparse refinement (`SparseSettings`; None: the library's)."""
    from ngc_gen.generate.shapes import auto_chunk, decode_shapes

    names = module.names[:n]
    shapes = decode_shapes(module, module.latents.weight[:n], names)
    out = []
    for shape in shapes:
        mesh = shape.mesh(resolution, chunk=auto_chunk(resolution), settings=settings,
                          progress=False).mesh
        path = workspace.mesh(run_dir, shape.name)
        atomic_write(path, lambda f, m=mesh: f.write(m.export(file_type="ply")))
        out.append(str(path))
    return out


def run_shape_latent(cfg: DictConfig) -> dict:
    import lightning as L

    from ngc_gen.data.datamodule import PreparedDataModule

    from .prepare_data import prepare_dataset

    cfg = with_stage_steps(cfg, "shape_latent")
    # bad data fails before the run directory is made; GCs of another layout before preparing
    found = {}
    prepared = prepare_dataset(cfg, check_annotations=lambda a: found.update(
        frame=check_layouts(a)))
    template, vectors = template_and_targets(prepared)
    run_dir = start_run(cfg)
    L.seed_everything(cfg.seed, workers=True, verbose=False)
    dm = PreparedDataModule(prepared, mode="ngc", batch_size=cfg.batch_size, seed=cfg.seed)
    module = build_module(cfg, template, vectors, prepared, found.get("frame"))
    trainer, train_s, start_step = train(cfg, run_dir, module, datamodule=dm)
    if trainer.global_rank != 0:
        return {}
    module = module.cpu().eval()
    last = workspace.last_checkpoint(run_dir)
    save_latents(workspace.latents(run_dir), module, last)
    metrics = evaluate(module, dm)
    metrics.update(steps=int(trainer.global_step), start_step=start_step, train_s=train_s,
                   n_shapes=len(prepared),
                   latent_dim=int(module.latents.weight.shape[1]), n_params=template.size,
                   gcs=template.names, frame=found.get("frame"), checkpoint=str(last),
                   latents=str(workspace.latents(run_dir)))
    n_prev = int(cfg.shape_latent.preview)
    if n_prev > 0:
        with torch.no_grad():
            metrics["preview"] = preview(module, run_dir, n_prev,
                                         int(cfg.shape_latent.preview_resolution),
                                         sparse_settings(cfg.extract.sparse))
    atomic_write_text(workspace.metrics(run_dir), json.dumps(metrics, indent=2))
    p = metrics["params"]
    print(f"\nshape latents: {len(prepared)} shapes x {module.latents.weight.shape[1]} dims, "
          f"{template.n_gcs} GCs, {template.size} GC parameters; {metrics['steps']} steps in "
          f"{train_s:.0f} s")
    print(f"  SDF L1 {metrics['l1']:.5f}   param MSE (std units) {metrics['param']:.5f}   "
          f"mean ||s||^2 {metrics['latent_norm2']:.3f}")
    print(f"  decoded GCs vs annotated: control points {p['point_mean']:.4f} mean / "
          f"{p['point_max']:.4f} max, radii {100 * p['radius_rel']:.2f}%, caps "
          f"{100 * p['cap_rel']:.2f}%, twist {p['twist_deg']:.2f} deg")
    f = found.get("frame")
    print("  body frame: " + (f"up {f['up']}, front {f['front']} (pictures, edits and samples "
                              f"use it)" if f else "none recorded (pictures detect up)"))
    hint = next_command("train.py", ["stage=diffusion", f"shape_latent_run={run_dir}"])
    print(f"run directory: {run_dir}\nnext: {hint}")
    return metrics
