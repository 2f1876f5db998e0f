"""Train entry point: `python train.py stage=<prepare|...> data=<dataset> ...` (Hydra)."""
import hydra
from omegaconf import DictConfig

import ngc_gen.config  # noqa: F401  (registers the ngc_root resolver)


@hydra.main(version_base="1.3", config_path="conf", config_name="train")
def main(cfg: DictConfig) -> None:
    from ngc_gen.cli import run_job
    from ngc_gen.stages import run_stage

    run_job(run_stage, cfg)


if __name__ == "__main__":
    main()
