"""Stage `reconstruct`: put new meshes into a trained model (DeepSDF's `reconstruct`).

    python train.py stage=reconstruct run=<fit or shape-latent run> data=folder data.path=DIR

A fit run: the new shapes' per-GC codes are optimised with the decoder frozen; the run's
checkpoints/last.ckpt is a fit checkpoint of the new shapes (`edit.py run=<this run>`).
A shape-latent run: one latent per new shape is optimised with the shape decoder and the NGC
decoder frozen (the shapes' annotations must follow the model's GC template); the shapes keep
their own GCs (the codes were fitted in those frames; `reconstruct.gcs=decoded` meshes the
latent's GCs instead), and with `reconstruct.refine_steps` > 0 the per-GC codes the latent
decodes to are then fitted further, decoders still frozen (DeepSDF's code fit, started inside
the model's latent space). The run writes latents.pt (sample.py can interpolate from them:
`latents=<this run>/latents.pt`; the path starts at the latent's own shape, without the code
refinement) and shapes.ckpt (the reconstructed shapes, refined codes and input GCs, for
edit.py). Both kinds write meshes/<name>.ply and metrics.json (Chamfer etc. against the input
meshes, as stage=fit does).
"""
from __future__ import annotations

import json
from pathlib import Path

import torch
from omegaconf import DictConfig, open_dict

from ngc_gen import workspace
from ngc_gen.data.atomic import atomic_write, atomic_write_text
from ngc_gen.data.errors import DataError

from ..runtime.checks import RECONSTRUCT_RUN_FIX as FIX
from ..runtime.config import instantiate, sparse_settings
from .settings import ReconstructSettings

# what a shape-latent reconstruction writes, as metrics.json's `outputs` and the run's printout
OUTPUTS = {
    "meshes/<name>.ply": "the reconstruction in the frame the model was trained in (the input "
                         "mesh normalised as prepared); metrics.json scores these against the "
                         "input",
    "shapes/<name>.ply, <name>.yaml": "the same surface with its GCs, mapped so the YAML's "
                                      "normalize: {bound: 0.8} is the identity (the sample.py "
                                      "convention): to edit or prepare again; rescaled, so a "
                                      "score against the raw input mesh differs from meshes/'s",
    workspace.SHAPES_CHECKPOINT: "the reconstructed shapes for edit.py run=<this run> shape=<name>",
    workspace.LATENTS: "one latent per shape: sample.py mode=interpolate latents=<this file>",
    workspace.PICTURES["reconstruct"]: "per shape the input mesh (left) beside its reconstruction (right)",
}


def explain_outputs(run_dir: Path) -> str:
    """The printed explanation of the run's files (OUTPUTS)."""
    width = max(len(k) for k in OUTPUTS)
    return "\n".join([f"outputs in {run_dir}:"] + [f"  {k:{width}s}  {v}"
                                                     for k, v in OUTPUTS.items()])


def checkpoint_kind(run) -> tuple[Path, str]:
    from ngc_gen.lit.checkpoint import load_checkpoint_dict, resolve_checkpoint

    path = resolve_checkpoint(run, fix=FIX, what="run to reconstruct into")
    kind = load_checkpoint_dict(path, fix=FIX).get("hyper_parameters", {}).get("checkpoint_kind")
    return path, kind


def run_reconstruct(cfg: DictConfig) -> dict:
    from ngc_gen.lit.autodecoder import CHECKPOINT_KIND as FIT
    from ngc_gen.lit.shape_latent import CHECKPOINT_KIND as SHAPE_LATENT

    path, kind = checkpoint_kind(cfg.get("run"))
    if kind not in (FIT, SHAPE_LATENT):
        raise DataError(f"{path} is neither a fit nor a shape-latent checkpoint (kind {kind!r})",
                        field="run", fix=FIX)
    recon = instantiate(cfg.reconstruct, "reconstruct")
    cfg = cfg.copy()
    with open_dict(cfg):
        cfg.trainer.max_steps = recon.max_steps
    if kind == FIT:
        return _codes(cfg, path, recon)
    return _latents(cfg, path, recon)


def _codes(cfg: DictConfig, path: Path, recon: ReconstructSettings) -> dict:
    import lightning as L

    from ngc_gen.data.datamodule import PreparedDataModule
    from ngc_gen.lit.checkpoint import load_autodecoder
    from ngc_gen.lit.reconstruct import codes_only_autodecoder

    from ..runtime.training import start_run, train
    from .fit import (named_gcs, prepared_up, print_metrics, render_comparison, score_fit,
                      shapes_meta)
    from .prepare_data import prepare_dataset

    fit = load_autodecoder(path)
    run_dir = start_run(cfg)
    prepared = prepare_dataset(cfg)
    kind = fit.hparams.kind
    L.seed_everything(cfg.seed, workers=True, verbose=False)
    dm = PreparedDataModule(prepared, mode=kind, batch_size=cfg.batch_size, seed=cfg.seed)
    module = codes_only_autodecoder(fit, dm.n_codes, shapes_meta(prepared, kind),
                                    code_lr=recon.code_lr)
    trained = train(cfg, run_dir, module, datamodule=dm)
    if trained.trainer.global_rank != 0:
        return {}
    metrics, gt = score_fit(cfg, module.cpu().eval(), prepared, run_dir)
    metrics.update(into=str(path), kind=kind, steps=int(trained.trainer.global_step),
                   train_s=trained.seconds,
                   checkpoint=str(workspace.last_checkpoint(run_dir)))
    atomic_write_text(workspace.metrics(run_dir), json.dumps(metrics, indent=2))
    render_comparison(gt, run_dir, gcs=named_gcs(prepared) if kind == "ngc" else None,
                      up=prepared_up(cfg.viz.up, prepared))
    print_metrics(metrics)
    print(f"run directory: {run_dir}\nedit one: python edit.py run={run_dir} "
          f"shape={prepared[0].name} edit=<program>")
    return metrics


def _refine_codes(cfg: DictConfig, module, prepared, run_dir: Path, meta: dict,
                  recon: ReconstructSettings):
    """reconstruct.refine_steps > 0: the per-GC codes the latents decode to, fitted further
    with every network weight frozen (run_dir/refine). Returns (N, K, C) codes or None."""
    import lightning as L

    from ngc_gen.data.datamodule import PreparedDataModule, training_rows
    from ngc_gen.lit.reconstruct import refine_codes_module

    from ..runtime.training import train

    steps = recon.refine_steps
    if steps <= 0:
        return None
    cfg = cfg.copy()
    with open_dict(cfg):
        cfg.trainer.max_steps = steps
    refine = refine_codes_module(module, module.latents.weight.detach(), meta,
                                 code_lr=recon.code_lr)
    ids, coords, sdf, _ = training_rows(prepared, "ngc")
    pick = torch.randperm(len(ids), generator=torch.Generator().manual_seed(0))[:65536]
    rows = ids[pick], coords[pick], sdf[pick]
    l1 = {"latent": _l1(lambda i, x: module.ngc(module.decode(module.latents.weight)[1].reshape(
        -1, module.ngc.code_dim)[i], x), rows), "before": _l1(refine.sdf, rows)}
    L.seed_everything(cfg.seed, workers=True, verbose=False)
    dm = PreparedDataModule(prepared, mode="ngc", batch_size=cfg.batch_size, seed=cfg.seed)
    train(cfg, run_dir / "refine", refine, datamodule=dm)
    refine = refine.cpu().eval()
    l1["after"] = _l1(refine.sdf, rows)
    K = module.template.n_gcs
    return refine.codes.weight.detach().cpu().reshape(len(prepared), K, -1).clone(), l1


@torch.no_grad()
def _l1(field, rows) -> float:
    """Mean |f - sdf| (unclamped) of field(ids, coords) on fixed training rows."""
    ids, coords, sdf = rows
    return float((field(ids, coords).reshape(-1) - sdf).abs().mean())


def _latents(cfg: DictConfig, path: Path, recon: ReconstructSettings) -> dict:
    import lightning as L

    from ngc_gen.data.datamodule import PreparedDataModule
    from ngc_gen.generate.shapes import write_edit_checkpoint
    from ngc_gen.lit.reconstruct import latent_only_module
    from ngc_gen.lit.shape_latent import ShapeLatentModule

    from ..runtime.training import start_run, train
    from .fit import prepared_up, print_metrics
    from .prepare_data import prepare_dataset
    from .train_shape_latent import save_latents, template_and_targets

    gcs_from = recon.gcs
    trained_model = ShapeLatentModule.from_checkpoint(path)
    run_dir = start_run(cfg)
    prepared = prepare_dataset(cfg)
    template, vectors = template_and_targets(prepared)
    if template.to_dict() != trained_model.template.to_dict():
        raise DataError(f"the meshes' GCs ({template.names}) do not follow the model's GC "
                        f"template ({trained_model.template.names}, with the same curve degrees "
                        "and keys)", field="data",
                        fix="annotate the meshes with the model's template (e.g. held-out "
                            "creatures), or reconstruct into a fit run instead")
    frame = (trained_model.hparams.meta or {}).get("frame")  # the model's body frame
    meta = {"dataset": str(cfg.data.name), "reconstructed_into": str(path), "frame": frame,
            "shapes": [{"name": s.name, "annotation_yaml": s.annotation_yaml} for s in prepared]}
    module = latent_only_module(trained_model, vectors, meta,
                                latent_lr=recon.latent_lr,
                                param_weight=recon.param_weight)
    L.seed_everything(cfg.seed, workers=True, verbose=False)
    dm = PreparedDataModule(prepared, mode="ngc", batch_size=cfg.batch_size, seed=cfg.seed)
    trained = train(cfg, run_dir, module, datamodule=dm)
    if trained.trainer.global_rank != 0:
        return {}
    module = module.cpu().eval()
    last = workspace.last_checkpoint(run_dir)
    save_latents(workspace.latents(run_dir), module, last)
    refined = (_refine_codes(cfg, module, prepared, run_dir, meta, recon)
               if gcs_from == "input" else None)
    res = int(cfg.extract.resolution)
    per, written = _mesh_reconstructions(cfg, module, prepared, run_dir, gcs_from, refined)
    write_edit_checkpoint(workspace.shapes_checkpoint(run_dir), module.ngc, written,
                          source=f"train.py stage=reconstruct run={path}")
    keys = [k for k, v in next(iter(per.values())).items() if not isinstance(v, bool)]
    mean = {k: float(sum(p[k] for p in per.values()) / len(per)) for k in keys}
    metrics = {"shapes": per, "mean": mean, "into": str(path), "kind": "shape_latent",
               "gcs": gcs_from, "refine_steps": 0 if refined is None else
               recon.refine_steps, "refine_l1": refined and refined[1],
               "steps": int(trained.trainer.global_step), "train_s": trained.seconds,
               "checkpoint": str(last), "latents": str(workspace.latents(run_dir)),
               "edit_checkpoint": str(workspace.shapes_checkpoint(run_dir)), "resolution": res,
               "outputs": OUTPUTS}
    picture = render_reconstruction(prepared, run_dir, up=prepared_up(cfg.viz.up, prepared))
    if picture is not None:
        metrics["picture"] = str(picture)
    atomic_write_text(workspace.metrics(run_dir), json.dumps(metrics, indent=2))
    print_metrics(metrics)
    print(explain_outputs(run_dir))
    print(f"run directory: {run_dir}\ninterpolate toward a generated shape: python sample.py "
          f"run=<diffusion run> mode=interpolate latents={workspace.latents(run_dir)} "
          f"a={prepared[0].name} b=0")
    return metrics


def _mesh_reconstructions(cfg: DictConfig, module, prepared, run_dir: Path, gcs_from: str,
                          refined) -> tuple[dict, list]:
    """Each reconstructed shape meshed (with the input's GCs or the decoded ones, the refined
    codes if any), scored against its input mesh and written (meshes/, shapes/).
    -> ({name: metrics}, written shapes)."""
    import trimesh

    from ngc_gen.eval import reconstruction_metrics
    from ngc_gen.generate.shapes import auto_chunk, decode_shapes, normalise, write_shape
    from ngc_gen.shape import recorded_gcs

    res = int(cfg.extract.resolution)
    settings = sparse_settings(cfg.extract.sparse)
    per, written = {}, []
    with torch.no_grad():
        shapes = decode_shapes(module, module.latents.weight, module.names)
        if gcs_from == "input":  # the codes were fitted in the input's GC frames: keep them
            shapes = [shape.replaced(gcs=recorded_gcs({"annotation_yaml": s.annotation_yaml}))
                      for shape, s in zip(shapes, prepared)]
        if refined is not None:
            shapes = [shape.replaced(codes=c) for shape, c in zip(shapes, refined[0])]
        for shape, s in zip(shapes, prepared):
            mesh = shape.mesh(res, float(cfg.extract.bound), chunk=auto_chunk(res),
                              settings=settings, progress=False).mesh
            gt = trimesh.Trimesh(s.mesh_vertices, s.mesh_faces, process=False)
            per[shape.name] = {k: v for k, v in reconstruction_metrics(
                mesh, gt, seed=cfg.metrics_seed).items() if isinstance(v, (int, float, bool))}
            atomic_write(workspace.mesh(run_dir, shape.name),
                         lambda f, m=mesh: f.write(m.export(file_type="ply")))
            m, gcs, _, _ = normalise(mesh, shape.gc_dicts())
            written.append(write_shape(run_dir / "shapes", shape.name, m, gcs, shape.codes,
                                       body=(module.hparams.meta or {}).get("frame")))
    return per, written


def render_reconstruction(prepared, run_dir: Path, up="auto", limit: int = 8):
    """run_dir/reconstruct.png: per shape (at most `limit`) the input mesh as prepared beside
    meshes/<name>.ply, in the same frame; None if it could not be drawn."""
    import trimesh

    from ngc_gen.viz import render_grid, render_or_warn

    rows = [[trimesh.Trimesh(s.mesh_vertices, s.mesh_faces, process=False),
             trimesh.load(workspace.mesh(run_dir, s.name), process=False)]
            for s in prepared[:limit]]
    return render_or_warn(render_grid, workspace.picture(run_dir, "reconstruct"), rows,
                          labels=[s.name for s in prepared[:limit]],
                          col_titles=["input", "reconstruction"], frame="row", up=up)
