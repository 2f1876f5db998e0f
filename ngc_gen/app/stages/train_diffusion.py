"""Stage `diffusion`: EDM latent diffusion on the latents of a shape-latent run.

    python train.py stage=diffusion shape_latent_run=<run dir or its checkpoint>

Reads the latents from the shape-latent checkpoint (the nn.Embedding it trained), standardises
them (statistics stored in the checkpoint), trains `LatentDiffusion` (EMA weights) and writes
checkpoints/last.ckpt, metrics.json and config.yaml to the run directory. The checkpoint's meta
records the shape-latent checkpoint, so `sample.py run=<this run>` finds everything.
"""
from __future__ import annotations

import json

import torch
from omegaconf import DictConfig
from torch.utils.data import RandomSampler, Sampler

from ngc_gen import workspace
from ngc_gen.data.atomic import atomic_write_text
from ngc_gen.data.errors import DataError

from ..runtime.next_hint import SAMPLE_KEYS, next_command
from .train_shape_latent import with_stage_steps

# settings of the `diffusion` group the stage reads itself (not LatentDiffusion arguments)
RUNNER_KEYS = ("batch_size", "batches_per_epoch", "max_steps", "pose_transfer", "augment")
EVAL_SEED, SAMPLE_SEED = 1, 0  # the EDM loss before/after and the nearest-neighbour samples


class Draws(Sampler):
    """The training draws of an epoch: `num_samples` latent indices of a seeded RandomSampler.
    Not itself a RandomSampler, so under DDP Lightning shards these draws across ranks
    (DistributedSamplerWrapper) instead of replacing them by one pass over the latents."""

    def __init__(self, n: int, num_samples: int, seed: int):
        self.inner = RandomSampler(range(n), num_samples=num_samples,
                                   generator=torch.Generator().manual_seed(int(seed)))

    def __iter__(self):
        return iter(self.inner)

    def __len__(self) -> int:
        return len(self.inner)


@torch.no_grad()
def nearest_neighbour_stats(samples: torch.Tensor, train: torch.Tensor, std: torch.Tensor) -> dict:
    """Distances in standardised units: each sample to its nearest training latent, and each
    training latent to its nearest other one (a sample far below the latter copies the data)."""
    a, b = samples / std, train / std
    d_st = torch.cdist(a, b).min(1).values
    d_tt = torch.cdist(b, b)
    d_tt.fill_diagonal_(float("inf"))
    d_tt = d_tt.min(1).values
    return {"sample_to_train_median": float(d_st.median()),
            "train_to_train_median": float(d_tt.median())}


def transferred_latents(shape_latent, settings) -> torch.Tensor:
    """`diffusion.pose_transfer` ({bodies, template, poses}): every body of the training shapes
    in the other bodies' training poses it lacks (poses=missing, the first of POSES and the one
    taken when unset) or in all of them (ngc_gen.generate.pose_transfer), parents from the GC
    template the shapes were made with."""
    from ngc_gen.data.autogc.template import load_template
    from ngc_gen.generate.pose_transfer import POSES, pose_transfer_latents

    template = load_template(settings.template)
    poses = settings.get("poses") or POSES[0]
    moved = pose_transfer_latents(shape_latent, list(settings.bodies),
                                  {g.name: g.parent for g in template.gcs}, poses)
    what = "the other bodies' poses it lacks" if poses == "missing" else "all the others' poses"
    print(f"pose transfer: {len(moved)} latents, every body in {what} ({template.name} "
          f"template)", flush=True)
    return moved


def template_parents(path, annotate: dict | None = None) -> dict:
    """{GC name: parent name} of a GC template file, or of an annotated mesh's YAML used as a
    template (its tree inferred, as `annotate.template` takes it)."""
    from .annotate import load_transfer_template

    return {g.name: g.parent for g in load_transfer_template(str(path), dict(annotate or {})).gcs}


AUGMENT_KEYS = ("template", "min_latents", "swing", "stretch", "scale", "twist", "swing_min_length",
                "transfer", "seed")


def augmented_latents(shape_latent, settings, annotate=None) -> torch.Tensor:
    """`diffusion.augment`: random GC edits of every training shape until there are
    `min_latents` latents (none when there are that many shapes), and with `transfer` every
    shape in each other's pose (ngc_gen.generate.augment)."""
    from ngc_gen.generate.augment import edited_latents, transferred_latents

    s = dict(settings)
    missing = [k for k in AUGMENT_KEYS if k not in s]
    if missing:
        raise DataError(f"diffusion.augment has no {missing}", field="diffusion.augment",
                        fix=f"give all of {list(AUGMENT_KEYS)} (conf/experiment/collection.yaml "
                            "holds the small-collection recipe's)")
    parents = template_parents(s["template"], annotate)
    n = len(shape_latent.names)
    copies = max(0, -(-int(s["min_latents"]) // n) - 1)
    if copies == 0:
        print(f"augment: {n} shapes, at least {s['min_latents']}: no GC edits", flush=True)
        return torch.zeros(0, shape_latent.latents.weight.shape[1])
    ranges = {k: s[k] for k in ("swing", "stretch", "scale", "twist", "swing_min_length")}
    out = [edited_latents(shape_latent, parents, copies, int(s["seed"]), **ranges)]
    if s["transfer"] and n > 1:
        out.append(transferred_latents(shape_latent, parents))
    out = torch.cat(out)
    print(f"augment: {len(out)} latents from GC edits of the {n} training shapes ({copies} each"
          f"{', and each in the others poses' if len(out) > copies * n else ''})", flush=True)
    return out


def run_diffusion(cfg: DictConfig) -> dict:
    import lightning as L
    from torch.utils.data import DataLoader, TensorDataset

    from ngc_gen.lit.checkpoint import resolve_checkpoint
    from ngc_gen.lit.shape_latent import FIX, ShapeLatentModule

    from ..runtime.config import instantiate_group
    from ..runtime.training import start_run, train

    cfg = with_stage_steps(cfg, "diffusion")
    ckpt = resolve_checkpoint(cfg.shape_latent_run, FIX, "shape-latent run").resolve()
    shape_latent = ShapeLatentModule.from_checkpoint(ckpt)
    latents = shape_latent.latents.weight.detach().float().clone()
    n_shapes = len(latents)
    if cfg.diffusion.get("pose_transfer"):
        latents = torch.cat([latents, transferred_latents(shape_latent,
                                                          cfg.diffusion.pose_transfer)])
    n_transferred = len(latents) - n_shapes
    if cfg.diffusion.get("augment"):
        latents = torch.cat([latents, augmented_latents(shape_latent, cfg.diffusion.augment,
                                                        cfg.get("annotate"))])
    run_dir = start_run(cfg, fixed_seeds={"edm_loss_eval": EVAL_SEED, "samples": SAMPLE_SEED})

    L.seed_everything(cfg.seed, workers=True, verbose=False)
    module = instantiate_group(
        cfg.diffusion, RUNNER_KEYS, dim=latents.shape[1],
        meta={"shape_latent_checkpoint": str(ckpt), "names": shape_latent.names,
              "n_latents": n_shapes, "frame": (shape_latent.hparams.meta or {}).get("frame")})
    module.fit_standardisation(latents)
    before = module.evaluate_loss(latents, seed=EVAL_SEED, repeats=8)
    dataset = TensorDataset(latents)
    batch = min(int(cfg.diffusion.batch_size), len(latents))
    sampler = Draws(len(dataset), batch * int(cfg.diffusion.batches_per_epoch), cfg.seed)
    loader = DataLoader(dataset, batch_size=batch, sampler=sampler, drop_last=True)
    trainer, train_s, start_step = train(cfg, run_dir, module, loader)
    if trainer.global_rank != 0:
        return {}
    module = module.cpu().eval()
    after = module.evaluate_loss(latents, seed=EVAL_SEED, repeats=8, use_ema=True)
    samples = module.sample(min(256, 4 * len(latents)), seed=SAMPLE_SEED)
    metrics = {"steps": int(trainer.global_step), "start_step": start_step, "train_s": train_s,
               "n_latents": n_shapes, "n_transferred": int(n_transferred),
               "n_augmented": int(len(latents) - n_shapes - n_transferred),
               "batch_size": batch,
               "dim": int(latents.shape[1]),
               "space_dim": module.space_dim,
               "pca_complete": module.hparams.pca_complete if module.space_dim != latents.shape[1]
               else None,
               "edm_loss_untrained": before, "edm_loss_ema": after,
               **nearest_neighbour_stats(samples, latents, module.latent_std),
               "frame": (shape_latent.hparams.meta or {}).get("frame"),
               "checkpoint": str(workspace.last_checkpoint(run_dir)),
               "shape_latent_checkpoint": str(ckpt)}
    atomic_write_text(workspace.metrics(run_dir), json.dumps(metrics, indent=2))
    rest = ", the others from the nearest latent" if metrics["pca_complete"] == "nearest" else ""
    space = f" ({module.space_dim} principal axes{rest})" if metrics["pca_complete"] else ""
    moved = (f" + {n_transferred} pose-transferred" if n_transferred else "") + (
        f" + {metrics['n_augmented']} GC-edited" if metrics["n_augmented"] else "")
    print(f"\ndiffusion: {n_shapes}{moved} latents x {latents.shape[1]} dims{space}, "
          f"{metrics['steps']} steps in {train_s:.0f} s; EDM loss {before:.3f} (untrained) -> "
          f"{after:.3f} (EMA)")
    print(f"  nearest training latent (std units): samples {metrics['sample_to_train_median']:.2f}"
          f" median, training latents to each other {metrics['train_to_train_median']:.2f}")
    hint = next_command("sample.py", [f"run={run_dir}", "mode=generate", "n=16"], keep=SAMPLE_KEYS)
    print(f"run directory: {run_dir}\nnext: {hint}")
    return metrics
