"""Edit entry point: `python edit.py run=<fit run or checkpoint> edit=<program> [shape=<name>]`
(Hydra, conf/edit.yaml); `program_file=<path.yaml>` runs a program from elsewhere. The runner is
ngc_gen.app.edit."""
import hydra
from omegaconf import DictConfig

from ngc_gen.app.cli import hydra_entry


@hydra.main(version_base="1.3", config_path="conf", config_name="edit")
def main(cfg: DictConfig) -> None:
    from ngc_gen.app.checks import check_edit
    from ngc_gen.app.cli import run_job
    from ngc_gen.app.edit import run_edit  # light: torch loads once run_edit starts the work

    run_job(run_edit, cfg, check=check_edit)


if __name__ == "__main__":
    hydra_entry(main)
