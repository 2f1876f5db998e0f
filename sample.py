"""Sample entry point: `python sample.py run=<diffusion run> mode=<generate|interpolate|mix|condition> ...`
or `python sample.py mode=export run=<run holding shapes> shape=<name>`
(Hydra, conf/sample.yaml). The runner is ngc_gen.app.sample."""
import hydra
from omegaconf import DictConfig

from ngc_gen.app.cli import hydra_entry


@hydra.main(version_base="1.3", config_path="conf", config_name="sample")
def main(cfg: DictConfig) -> None:
    from ngc_gen.app.checks import check_sample
    from ngc_gen.app.cli import run_job
    from ngc_gen.app.export import check_export

    def run(cfg):  # torch loads here, after check_sample
        from ngc_gen.app.sample import run_sample

        return run_sample(cfg)

    run_job(run, cfg, check=check_export if cfg.get("mode") == "export" else check_sample)


if __name__ == "__main__":
    hydra_entry(main)
