"""Stage `fit`: prepare, train the auto-decoder with Lightning, extract meshes, write metrics.

Run directory: checkpoints/ (last.ckpt, best.ckpt), meshes/<shape>.ply, metrics.json,
config.yaml (resolved), logs/.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import torch
import trimesh
import hydra
from omegaconf import DictConfig
from tqdm import tqdm

from ngc_gen import workspace
from ngc_gen.data.atomic import atomic_write, atomic_write_text
from ngc_gen.data.prepare import PreparedShape

from ..runtime.config import sparse_settings
from .prepare_data import prepare_dataset
from ..runtime.config import instantiate_group
from ..runtime.training import start_run, train


def shapes_meta(prepared: list[PreparedShape], kind: str) -> dict:
    """What a checkpoint must carry to rebuild every shape: names, GCs and code offsets."""
    shapes, offset = [], 0
    for i, s in enumerate(prepared):
        n = len(s.gc_names) if kind == "ngc" else 1
        shapes.append({"name": s.name, "code_offset": offset, "n_codes": n,
                       "annotation_yaml": s.annotation_yaml})
        offset += n
    return {"shapes": shapes}


def model_kind(cfg: DictConfig) -> str:
    """'ngc' or 'deepsdf': the kind of the `model` group's decoder class (not built)."""
    return hydra.utils.get_class(cfg.model.decoder._target_).kind


def build_module(cfg: DictConfig, n_codes: int, meta: dict):
    """The `model` group's AutoDecoder (`_target_`) with n_codes codes."""
    return instantiate_group(cfg.model, n_codes=n_codes, meta=meta)


def union_blend(cfg: DictConfig) -> float:
    """The blend width the loss's row shares use: the run's `model.union` width with kind blend
    and loss_shares (0: rows unweighted, as for the min or a model without GCs)."""
    union = cfg.model.get("union")
    shares = union and union.get("kind") == "blend" and union.get("loss_shares", False)
    return float(union.width) if shares else 0.0


def run_fit(cfg: DictConfig) -> dict:
    import lightning as L

    from ngc_gen.data.datamodule import PreparedDataModule

    prepared = prepare_dataset(cfg)  # bad data fails before the run directory is made
    run_dir = start_run(cfg)
    L.seed_everything(cfg.seed, workers=True, verbose=False)
    kind = model_kind(cfg)
    dm = PreparedDataModule(prepared, mode=kind, batch_size=cfg.batch_size, seed=cfg.seed,
                            code_balance=cfg.code_balance,
                            junction_weight=cfg.junction_weight, blend=union_blend(cfg))
    module = build_module(cfg, dm.n_codes, shapes_meta(prepared, kind))
    trainer, train_s, start_step = train(cfg, run_dir, module, datamodule=dm)
    if trainer.global_rank != 0:
        return {}
    module = module.cpu().eval()
    metrics, gt = score_fit(cfg, module, prepared, run_dir)
    metrics.update(steps=int(trainer.global_step), start_step=start_step, train_s=train_s,
                   kind=kind,
                   checkpoint=str(workspace.last_checkpoint(run_dir)))
    atomic_write_text(workspace.metrics(run_dir), json.dumps(metrics, indent=2))
    render_comparison(gt, run_dir, gcs=named_gcs(prepared) if kind == "ngc" else None,
                      up=prepared_up(cfg.viz.up, prepared))
    print_metrics(metrics)
    print(f"run directory: {run_dir}")
    return metrics


def score_fit(cfg: DictConfig, module, prepared: list[PreparedShape], run_dir: Path):
    """(metrics, ground truth): every shape of a trained AutoDecoder meshed into
    run_dir/meshes and scored against its prepared mesh and GCs (`reconstruct`), settings from
    the `extract` and `metrics` groups and `metrics_seed`."""
    gt = {s.name: (s.mesh_vertices, s.mesh_faces) for s in prepared}
    mesh_kwargs = ({} if module.hparams.kind == "deepsdf"   # its own world-space extractor
                   else {"settings": sparse_settings(cfg.extract.sparse)})
    with torch.no_grad():
        metrics = reconstruct(module, workspace.meshes(run_dir), gt,
                              resolution=cfg.extract.resolution, bound=cfg.extract.bound,
                              chunk=cfg.extract.chunk, seed=cfg.metrics_seed,
                              gcs=named_gcs(prepared), junctions=junction_settings(cfg),
                              **mesh_kwargs)
    return metrics, gt


def junction_settings(cfg: DictConfig) -> dict:
    """`metrics.junctions` (conf/metrics/default.yaml) as keyword arguments of
    `ngc_gen.eval.junction_metrics`."""
    from omegaconf import OmegaConf

    return OmegaConf.to_container(cfg.metrics.junctions, resolve=True)


def named_gcs(prepared: list[PreparedShape]) -> dict:
    """{shape name: its GCs} of prepared shapes (what an NGC fit's edit programs refer to)."""
    return {s.name: s.gcs() for s in prepared}


def comparison_rows(gt: dict, meshes_dir: Path, gcs: dict | None = None) -> list[list]:
    """The rows of meshes.png, one per shape: the ground truth (with its GCs translucent and
    each labelled with its name at its curve's middle, if `gcs` {shape: GCs} has the shape)
    beside the fitted mesh meshes_dir/<shape>.ply."""
    import trimesh

    from ngc_gen.viz import gc_labels, gcs_surface

    rows = []
    for n, (V, F) in gt.items():
        truth = trimesh.Trimesh(V, F, process=False)
        if gcs and gcs.get(n):
            truth = (truth, gcs_surface(gcs[n]), gc_labels(gcs[n]))
        rows.append([truth, trimesh.load(meshes_dir / f"{n}.ply", process=False)])
    return rows


def prepared_up(spec, prepared):
    """`viz.up` for a picture of prepared shapes: the body frame they all record, when they do
    (`viz.camera.frame_up`)."""
    from ngc_gen.data.body_frame import shared_frame
    from ngc_gen.viz.camera import frame_up

    return frame_up(spec, shared_frame([s.annotation().frame for s in prepared]))


def render_comparison(gt: dict, run_dir: Path, gcs: dict | None = None, up="auto") -> None:
    """run_dir/meshes.png: ground truth beside the fitted mesh, one row per shape; with `gcs`
    ({shape: GCs}) the GCs are drawn over the ground truth with their names. `up`: `viz.up`.
    A failed render (no off-screen OpenGL) is reported, not fatal: the meshes are written."""
    from ngc_gen.viz import render_grid, render_or_warn

    rows = comparison_rows(gt, workspace.meshes(run_dir), gcs)
    render_or_warn(render_grid, workspace.picture(run_dir, "fit"), rows,
                   labels=list(gt), col_titles=["ground truth" + (", GCs by name" if gcs else ""),
                                                "fitted"], frame="row", up=up)


PRINTED = {"cd": "cd", "hd": "hd", "emd": "emd", "cd_l1": "cd_l1", "fscore": "fscore",
           "normal_consistency": "normal_consistency", "fragments": "fragments",
           "junction_ratio_dist": "jct_dist", "junction_ratio_normal": "jct_normal",
           "extra_pieces": "extra_pieces"}   # metrics key -> column of the printed table


def _num(x) -> float:
    return float("nan") if x is None else x


def print_metrics(metrics: dict) -> None:
    cols = {k: h for k, h in PRINTED.items()
            if k in metrics["mean"] or not k.startswith(("junction", "extra"))}
    w = {c: max(12, len(h) + 2) for c, h in cols.items()}
    print(f"\n{'shape':20s}" + "".join(f"{h:>{w[c]}s}" for c, h in cols.items())
          + f"{'watertight':>12s}")
    for name, m in {**metrics["shapes"], "mean": metrics["mean"]}.items():
        vals = "".join(f"{_num(m.get(c)):{w[c]}.3g}" for c in cols)
        print(f"{name:20s}{vals}{str(m.get('watertight', '')):>12s}")
    print("cd: DeepSDF Chamfer (30k points each way, squared, summed means); hd: Hausdorff; "
          "emd: exact assignment on 2048 points; fscore@0.01; fragments: components under 1% "
          "of the faces" + ("; jct_dist, jct_normal: error (distance, normal angle) where GCs "
                            "meet / elsewhere; extra_pieces: loose pieces the truth has not"
                            if "extra_pieces" in cols else ""))


def reconstruct(module, out_dir: Path, gt: dict, resolution: int = 256, bound: float = 1.0,
                chunk: int = 65536, seed: int = 0, gcs: dict | None = None,
                junctions: dict | None = None, **mesh_kwargs) -> dict:
    """Extract every shape into out_dir/<name>.ply and score it against its ground truth
    gt[name] = (vertices, faces) in the normalised frame. Returns {shapes, mean}.
    With `gcs` ({name: its GCs}) each shape also gets the junction measure
    (`ngc_gen.eval.junction_metrics`, keyword arguments `junctions`); a junction figure's
    mean is over the shapes that have one (a shape with one GC has none: None).
    mesh_kwargs go to `autodecoder_mesh` (e.g. coarse_step for a DeepSDF module)."""
    from ngc_gen.eval import junction_metrics, reconstruction_metrics
    from ngc_gen.eval.junctions import FIGURES as JUNCTION_FIGURES
    from ngc_gen.shape import autodecoder_mesh

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    per = {}
    shapes = module.hparams.meta["shapes"]
    for i, meta in enumerate(tqdm(shapes, desc="extract", unit="shape", disable=len(shapes) < 2)):
        res = autodecoder_mesh(module, i, resolution, bound, chunk, **mesh_kwargs)
        atomic_write(out_dir / f"{meta['name']}.ply",
                     lambda f, m=res.mesh: f.write(m.export(file_type="ply")))
        V, F = gt[meta["name"]]
        truth = trimesh.Trimesh(V, F, process=False)
        m = reconstruction_metrics(res.mesh, truth, seed=seed)
        if gcs is not None:
            m.update(junction_metrics(res.mesh, truth, gcs[meta["name"]], seed=seed,
                                      **(junctions or {})))
        m.update(n_network_evals=int(res.stats["n_network_evals"]),
                 extract_s=float(res.stats["seconds"]))
        per[meta["name"]] = {k: (float(v) if isinstance(v, (float, np.floating)) else v)
                             for k, v in m.items()}
    keys = [k for k, v in next(iter(per.values())).items()
            if isinstance(v, (int, float)) and not isinstance(v, bool)]
    mean = {k: float(np.mean([p[k] for p in per.values()])) for k in keys
            if k not in JUNCTION_FIGURES}
    if gcs is not None:  # over the shapes that have the figure (None: no junction sample)
        for k in JUNCTION_FIGURES:
            have = [p[k] for p in per.values() if p.get(k) is not None]
            mean[k] = float(np.mean(have)) if have else None
    mean["watertight"] = float(np.mean([bool(p.get("watertight")) for p in per.values()]))
    return {"shapes": per, "mean": mean, "resolution": resolution}
