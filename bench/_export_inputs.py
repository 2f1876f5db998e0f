"""What bench/export.py exports, built on a fresh clone and cached under .cache/bench/export:

- generated animals: the animals recipe (conf/experiment/animals.yaml) at a stated, reduced
  cost (3 species, one frame per clip, 2500 shape-latent steps on 20k samples a shape, 1500
  diffusion steps without pose transfer), then `sample.py mode=generate` of 4 animals;
- a fit of data=demo (the ant and 3 creatures, model=small, 1500 steps) for the edit programs'
  clips (`posed_ant_leg`, `bent_tail`).

Each stage goes through the bench harness's FitCache (keyed by its whole config and its
dataset's bytes), so a second run reuses them and a changed recipe trains again."""
from __future__ import annotations

import time
from pathlib import Path

from bench._harness import FitCache, cached_stage, config_recipe, dataset_identity

ROOT = Path(__file__).resolve().parents[1]
CACHE = ROOT / ".cache/bench/export"
SPECIES = "[horse,wolf,cow]"
ANIMAL_STEPS = {"shape_latent": 2500, "diffusion": 1500}
FIT_STEPS = 1500
N_ANIMALS = 4


def _say(msg: str) -> None:
    print(f"[export inputs {time.strftime('%H:%M:%S')}] {msg}", flush=True)


def _base(threads: int) -> list[str]:
    return ["trainer.enable_progress_bar=false", "logger=csv", "seed=0", f"threads={threads}"]


def animals(cache: FitCache, resolution: int, threads: int) -> tuple[Path, str]:
    """(the generate output folder holding sample_000 ..., how it was made)."""
    from ngc_gen.app.runtime.config import compose_config
    from ngc_gen.app.stages.train_diffusion import run_diffusion
    from ngc_gen.app.stages.train_shape_latent import run_shape_latent

    base = ["experiment=animals", "data.frames=1", f"data.species={SPECIES}",
            "data.heldout_species=[]",
            "prepare.n_samples=20000", "prepare.cache_dir=${paths.cache_dir}/prepared/animals_f1_20k",
            "batch_size=2048", *_base(threads)]
    _say("animals: shape latents (cached after the first run)")
    sl = cached_stage(cache, "shape_latent", compose_config(overrides=[
        *base, "stage=shape_latent", "shape_latent.preview=0",
        f"shape_latent.max_steps={ANIMAL_STEPS['shape_latent']}"]), run_shape_latent,
        leave_out=("diffusion",))
    _say(f"animals: shape latents in {sl.run_dir}; diffusion")
    diff = cached_stage(cache, "diffusion", compose_config(overrides=[
        *base, "stage=diffusion", f"shape_latent_run={sl.run_dir}",
        f"diffusion.max_steps={ANIMAL_STEPS['diffusion']}", "diffusion.pose_transfer=null"]),
        run_diffusion)
    _say(f"animals: diffusion in {diff.run_dir}; generating {N_ANIMALS} animals")

    def gen(run_dir: Path) -> dict:
        from ngc_gen.app.stages.sample import generate
        from ngc_gen.generate import load_generator

        t0 = time.perf_counter()
        generate(load_generator(diff.run_dir), run_dir, n=N_ANIMALS, seed=0,
                 resolution=resolution, progress=False)
        return {"stage_s": time.perf_counter() - t0, "label": "generate"}

    g = cache.get({"stage": "generate", "diffusion": diff.key, "n": N_ANIMALS, "seed": 0,
                   "resolution": resolution}, gen)
    made = (f"animals: train.py experiment=animals data.frames=1 data.species={SPECIES} "
            f"data.heldout_species=[] "
            f"prepare.n_samples=20000 batch_size=2048 threads={threads} stage=shape_latent "
            f"shape_latent.max_steps={ANIMAL_STEPS['shape_latent']}; stage=diffusion "
            f"diffusion.max_steps={ANIMAL_STEPS['diffusion']} diffusion.pose_transfer=null; "
            f"sample.py mode=generate n={N_ANIMALS} seed=0 extract.resolution={resolution}")
    return g.run_dir, made


def demo_fit(cache: FitCache, threads: int) -> tuple[Path, str]:
    """(the fit run of data=demo holding ant and creature_0000, how it was made)."""
    from omegaconf import open_dict

    from ngc_gen.app.runtime.config import compose_config
    from ngc_gen.app.stages.fit import run_fit

    cfg = compose_config(overrides=["stage=fit", "data=demo", "model=small",
                                    f"trainer.max_steps={FIT_STEPS}", *_base(threads)])
    _say("demo fit: the ant and 3 creatures (cached after the first run)")

    def fit(run_dir: Path) -> dict:
        with open_dict(cfg):
            cfg.run_dir = str(run_dir)
        t0 = time.perf_counter()
        run_fit(cfg)
        return {"stage_s": time.perf_counter() - t0, "label": "demo fit"}

    f = cache.get({"stage": "fit", "config": config_recipe(cfg), "data": dataset_identity(cfg)},
                  fit)
    return f.run_dir, (f"fit: train.py stage=fit data=demo model=small "
                       f"trainer.max_steps={FIT_STEPS} threads={threads}")


def build(resolution: int, threads: int = 1) -> dict:
    """{animals: dir, fit: dir, made_with: text}, trained now where not cached (on `threads`
    torch threads: the count is part of each stage's cached recipe)."""
    cache = FitCache("inputs", root=CACHE)
    fit, fit_made = demo_fit(cache, threads)
    gen, gen_made = animals(cache, resolution, threads)
    _say(f"inputs ready: animals {gen}, fit {fit}")
    return {"animals": gen, "fit": fit, "made_with": f"{gen_made}. {fit_made}"}


if __name__ == "__main__":
    build(96)
