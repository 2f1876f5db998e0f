"""Sample entry point: `python sample.py run=<diffusion run> mode=<generate|interpolate|mix>`."""
import hydra
from omegaconf import DictConfig

import ngc_gen.config  # noqa: F401  (registers the ngc_root resolver)


@hydra.main(version_base="1.3", config_path="conf", config_name="sample")
def main(cfg: DictConfig) -> None:
    from ngc_gen.cli import user_errors
    from ngc_gen.generate import run_sample

    with user_errors():
        run_sample(cfg)


if __name__ == "__main__":
    main()
