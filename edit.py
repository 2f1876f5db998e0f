"""Edit entry point: `python edit.py ckpt=<run>/checkpoints/last.ckpt edit=<program> [shape=<name>]`
(Hydra). Programs live in conf/edit/*.yaml; `program_file=<path.yaml>` runs one from elsewhere."""
import hydra
from omegaconf import DictConfig

import ngc_gen.config  # noqa: F401  (registers the ngc_root resolver)


@hydra.main(version_base="1.3", config_path="conf", config_name="edit")
def main(cfg: DictConfig) -> None:
    from ngc_gen.cli import run_job
    from ngc_gen.edit.run import run_edit

    run_job(run_edit, cfg)


if __name__ == "__main__":
    main()
