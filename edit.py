"""Edit entry point: `python edit.py run=<fit run or checkpoint> edit=<program> [shape=<name>]`
(Hydra, conf/edit.yaml); `program_file=<path.yaml>` runs a program from elsewhere. The runner is
ngc_gen.app.stages.edit_shapes."""
import hydra
from omegaconf import DictConfig

from ngc_gen.app.runtime.cli import hydra_entry


@hydra.main(version_base="1.3", config_path="conf", config_name="edit")
def main(cfg: DictConfig) -> None:
    from ngc_gen.app.runtime.cli import run_job
    from ngc_gen.app.stages.registry import COMMANDS

    command = COMMANDS["edit"]  # its runner (and torch) loads after its checks
    run_job(command.run, cfg, check=command.check)


if __name__ == "__main__":
    hydra_entry(main)
