"""Train entry point: `python train.py stage=<prepare|fit|shape_latent|diffusion|pipeline> ...`
(Hydra, conf/train.yaml); the stages are ngc_gen.app's runners."""
import hydra
from omegaconf import DictConfig

from ngc_gen.app.runtime.cli import hydra_entry


@hydra.main(version_base="1.3", config_path="conf", config_name="train")
def main(cfg: DictConfig) -> None:
    from ngc_gen.app.runtime.cli import run_job
    from ngc_gen.app.stages.registry import check_inputs, run_stage

    run_job(run_stage, cfg, check=check_inputs)


if __name__ == "__main__":
    hydra_entry(main)
