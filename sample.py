"""Sample entry point: `python sample.py run=<diffusion run> mode=<generate|interpolate|mix>`."""
import hydra
from omegaconf import DictConfig

import ngc_gen.config  # noqa: F401  (registers the ngc_root resolver)


@hydra.main(version_base="1.3", config_path="conf", config_name="sample")
def main(cfg: DictConfig) -> None:
    from ngc_gen.cli import run_job
    from ngc_gen.generate import run_sample

    run_job(run_sample, cfg)


if __name__ == "__main__":
    main()
