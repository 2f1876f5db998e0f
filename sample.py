"""Sample entry point: `python sample.py run=<diffusion run> mode=<generate|interpolate|mix> ...`,
or `python sample.py mode=export run=<run holding shapes> shape=<name>` (Hydra,
conf/sample.yaml). The runners are ngc_gen.app.stages.sample and .export_shape."""
import hydra
from omegaconf import DictConfig

from ngc_gen.app.runtime.cli import hydra_entry


@hydra.main(version_base="1.3", config_path="conf", config_name="sample")
def main(cfg: DictConfig) -> None:
    from ngc_gen.app.runtime.cli import run_job
    from ngc_gen.app.stages.registry import COMMANDS

    # its runner (and torch) loads after its checks; mode=export has its own
    command = COMMANDS["export" if cfg.get("mode") == "export" else "sample"]
    run_job(command.run, cfg, check=command.check)


if __name__ == "__main__":
    hydra_entry(main)
