"""Sample entry point: `python sample.py run=<diffusion run> mode=<generate|interpolate|mix> ...`
(Hydra, conf/sample.yaml). The runner is ngc_gen.app.stages.sample."""
import hydra
from omegaconf import DictConfig

from ngc_gen.app.runtime.cli import hydra_entry


@hydra.main(version_base="1.3", config_path="conf", config_name="sample")
def main(cfg: DictConfig) -> None:
    from ngc_gen.app.runtime.cli import run_job
    from ngc_gen.app.stages.registry import COMMANDS

    command = COMMANDS["sample"]  # its runner (and torch) loads after its checks
    run_job(command.run, cfg, check=command.check)


if __name__ == "__main__":
    hydra_entry(main)
