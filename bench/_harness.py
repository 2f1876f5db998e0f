"""The benches' shared harness: one machine record, one atomic result writer, one keyed fit cache.

Every script in bench/ writes its result through `Bench.write`, so every bench/results/<name>.json
carries the same `machine` record, and every bench that trains a model goes through `FitCache`,
so a fit is reused exactly when its whole recipe is unchanged. The module imports only the
standard library and ngc_gen/data/atomic.py (torch and omegaconf are imported inside the
functions that need them): bench/demo.py runs it with a bare `python3`.

Example (a new bench: docs/contributing.md, "Add a bench")::

    from bench._harness import Bench, FitCache, config_recipe, file_identity

    def main():
        bench = Bench("mybench")             # load before, commit, date: taken now
        from ngc_gen.app.runtime.config import compose_config
        from ngc_gen.app.stages.fit import run_fit

        cfg = compose_config(overrides=["stage=fit", "data=demo", "model=small"])
        recipe = {"config": config_recipe(cfg),          # the whole resolved config
                  "data": file_identity([ROOT / "datasets/ant/ant.yaml"])}

        def train(run_dir):                  # called only when no fit has this recipe
            cfg.run_dir = str(run_dir)
            m = run_fit(cfg)
            return {"checkpoint": m["checkpoint"], "train_s": m["train_s"]}

        fit = FitCache("mybench").get(recipe, train)     # fit.run_dir, fit.info, fit.reused
        bench.write({"cd": 1.2e-4, "train_s": fit.info["train_s"]})
        # -> bench/results/mybench.json: {"cd": ..., "train_s": ..., "machine": {...}}

A bench that reads another bench's fit asks the cache for it (`latest_fit("deform")`), never
imports the other bench's module.

The machine record (`MACHINE_KEYS`, the same keys in every result):
  cpus              os.cpu_count()
  torch_threads     torch.get_num_threads() when the result is written (None: torch not loaded)
  python, torch     versions (torch None when not loaded)
  commit, dirty     `git rev-parse HEAD` of the checkout, and whether tracked files differed
  date_utc          when the bench started, ISO 8601 UTC
  load_1min_before  1-minute load average when the bench started (`Bench(...)`)
  load_1min_after   the same when the result was written
A bench that measures something else than this process (demo.py times a fresh clone) passes
the right values to `write` (`commit=...`, `torch_threads=...`). Results are written with
the package's atomic writer (ngc_gen/data/atomic.py: a reader sees the old file or the whole new
one; a new file gets 0666 less the umask).
"""
from __future__ import annotations

import hashlib
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable

from ngc_gen.data.atomic import atomic_write_text

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench/results"
FITS = ROOT / ".cache/bench/fits"   # gitignored (.cache/)

MACHINE_KEYS = ("cpus", "torch_threads", "python", "torch", "commit", "dirty", "date_utc",
                "load_1min_before", "load_1min_after")


# ---- the machine ----------------------------------------------------------------------------
def load_1min() -> float | None:
    """The 1-minute load average now (None where the platform has none)."""
    try:
        return round(os.getloadavg()[0], 2)
    except (AttributeError, OSError):
        return None


def load_avg() -> list[float]:
    """The 1-, 5- and 15-minute load averages now, rounded to 0.01 ([] where the platform has
    none): for a bench that records the load around each of its runs (bench/fit.py)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        return []


def git_commit(root: Path = ROOT) -> tuple[str | None, bool | None]:
    """(HEAD's full hash, whether tracked files differ from it) of the checkout at `root`;
    (None, None) outside a git checkout."""
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], check=True,
                              capture_output=True, text=True).stdout.strip()
        status = subprocess.run(["git", "-C", str(root), "status", "--porcelain",
                                 "--untracked-files=no"], check=True, capture_output=True,
                                text=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return None, None
    return head, bool(status.strip())


def now_utc() -> str:
    return datetime.now(timezone.utc).replace(microsecond=0).isoformat().replace("+00:00", "Z")


def machine(load_before: float | None = None, date_utc: str | None = None,
            **overrides) -> dict:
    """The machine record (MACHINE_KEYS), its after-load taken now. `overrides` replace
    recorded values (only MACHINE_KEYS are accepted)."""
    unknown = set(overrides) - set(MACHINE_KEYS)
    if unknown:
        raise KeyError(f"machine(): unknown keys {sorted(unknown)}; the record's keys are "
                       f"{list(MACHINE_KEYS)}")
    torch = sys.modules.get("torch")
    commit, dirty = git_commit()
    rec = {"cpus": os.cpu_count(),
           "torch_threads": torch.get_num_threads() if torch is not None else None,
           "python": platform.python_version(),
           "torch": getattr(torch, "__version__", None) if torch is not None else None,
           "commit": commit, "dirty": dirty, "date_utc": date_utc or now_utc(),
           "load_1min_before": load_before, "load_1min_after": load_1min()}
    rec.update(overrides)
    return rec


# ---- writing results ------------------------------------------------------------------------
def dumps(result: dict) -> str:
    """The results' JSON text: indented, one trailing newline (NaN refused: it is not JSON)."""
    return json.dumps(result, indent=2, allow_nan=False) + "\n"


class Bench:
    """One bench run: `Bench(name)` at the start records the load, the date and the commit;
    `write(result)` writes bench/results/<name>.json with the machine record added."""

    def __init__(self, name: str, results: Path | None = None):
        self.name, self.results = name, Path(results if results is not None else RESULTS)
        self.load_before, self.date_utc = load_1min(), now_utc()

    @property
    def path(self) -> Path:
        return self.results / f"{self.name}.json"

    def machine(self, **overrides) -> dict:
        return machine(self.load_before, self.date_utc, **overrides)

    def write(self, result: dict, path: str | os.PathLike | None = None,
              **machine_overrides) -> Path:
        """Atomically write `result` plus `machine` (taken now) to `path` (default
        bench/results/<name>.json). The result must not carry its own `machine`."""
        if "machine" in result:
            raise ValueError(f"{self.name}: the result has its own 'machine' entry; the "
                             "harness writes it (pass corrections as keyword arguments)")
        out = {**result, "machine": self.machine(**machine_overrides)}
        return atomic_write_text(self.path if path is None else path, dumps(out))


# ---- the fit cache --------------------------------------------------------------------------
def _normalise(x):
    """A recipe as plain JSON values, paths inside the checkout as '<repo>/...' (a key does
    not depend on where the checkout is)."""
    if isinstance(x, dict):
        return {str(k): _normalise(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_normalise(v) for v in x]
    if isinstance(x, os.PathLike):
        x = os.fspath(x)
    if isinstance(x, str):
        return x.replace(str(ROOT), "<repo>")
    if x is None or isinstance(x, (bool, int, float)):
        return x
    raise TypeError(f"a fit recipe holds JSON values only; got {type(x).__name__}: {x!r}")


def recipe_key(recipe: dict) -> str:
    """16 hex digits of sha256 over the recipe's canonical JSON (keys sorted)."""
    text = json.dumps(_normalise(recipe), sort_keys=True, allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def file_identity(paths) -> dict:
    """{path: sha256 of its bytes} for files, and for folders over every file below them
    (relative names and bytes). A missing path raises: build the data before keying a fit on
    it, or the key would change once the fit has built it."""
    out = {}
    for p in map(Path, paths):
        h = hashlib.sha256()
        if p.is_dir():
            for f in sorted(q for q in p.rglob("*") if q.is_file()):
                h.update(str(f.relative_to(p)).encode() + b"\0" + f.read_bytes() + b"\0")
        elif p.is_file():
            h.update(p.read_bytes())
        else:
            raise FileNotFoundError(f"fit recipe: {p} does not exist (build the data first)")
        out[str(_normalise(str(p.resolve())))] = h.hexdigest()[:16]
    return out


#: settings added after fits were cached, at the value that does what the code did before
#: they existed: left out of a recipe while they hold it, so adding a setting does not
#: invalidate every cached fit (a fit with any other value gets its own key)
NEUTRAL = {("junction_weight",): 0.0, ("prepare", "pair_margin"): 0.0,
           ("prepare", "shell_fraction"): 0.0, ("prepare", "shell_width"): 0.1,
           ("prepare", "overlap_fraction"): 0.0,
           ("diffusion", "pose_transfer"): None, ("diffusion", "pca_complete"): "mean"}


def config_recipe(cfg) -> dict:
    """A composed Hydra config as a recipe: resolved, with `run_dir` (where the fit goes, which
    the cache chooses) replaced by a placeholder and `NEUTRAL` settings at their neutral value
    left out."""
    import copy

    from omegaconf import OmegaConf, open_dict

    c = copy.deepcopy(cfg)
    with open_dict(c):
        c.run_dir = "<run_dir>"
    out = OmegaConf.to_container(c, resolve=True)
    for path, value in NEUTRAL.items():
        *parents, leaf = path
        node = out
        for k in parents:
            node = node.get(k) if isinstance(node, dict) else None
        if isinstance(node, dict) and leaf in node and node[leaf] == value:
            del node[leaf]
    return out


@dataclass
class Fit:
    run_dir: Path      # what the fit wrote (its checkpoints, meshes, metrics)
    key: str
    info: dict         # what the fit function returned
    recipe: dict
    reused: bool       # True: found in the cache; False: fitted in this call


class FitCache:
    """Fits of one bench keyed by their recipe: <root>/<bench>/<key>/, complete once its
    fit.json is written. `get` reuses a complete fit of the same recipe and otherwise fits
    again into a fresh folder, so a changed recipe (config, data bytes, steps, seed) can never
    pick up an old fit; an interrupted fit (no fit.json) is discarded."""

    def __init__(self, bench: str, root: Path = FITS):
        self.dir = Path(root) / bench

    def run_dir(self, recipe: dict) -> Path:
        return self.dir / recipe_key(recipe)

    def get(self, recipe: dict, fit: Callable[[Path], dict], refit: bool = False) -> Fit:
        """The fit of `recipe`: from the cache, or `fit(run_dir)` (which trains into run_dir
        and returns a JSON-able dict, e.g. checkpoint path and train_s) run now."""
        key = recipe_key(recipe)
        run_dir = self.dir / key
        done = run_dir / "fit.json"
        if done.is_file() and not refit:
            rec = json.loads(done.read_text())
            if rec.get("key") == key:
                return Fit(run_dir, key, rec["info"], rec["recipe"], True)
        shutil.rmtree(run_dir, ignore_errors=True)   # an interrupted or forced fit
        run_dir.mkdir(parents=True)
        info = fit(run_dir)
        commit, dirty = git_commit()
        rec = {"key": key, "recipe": _normalise(recipe), "info": _normalise(info),
               "date_utc": now_utc(), "commit": commit, "dirty": dirty}
        atomic_write_text(done, dumps(rec))
        return Fit(run_dir, key, rec["info"], rec["recipe"], False)

    def entries(self) -> list[Fit]:
        """Every complete fit in this bench's cache, oldest first."""
        out = []
        for done in self.dir.glob("*/fit.json"):
            rec = json.loads(done.read_text())
            out.append((rec.get("date_utc", ""), Fit(done.parent, rec["key"], rec["info"],
                                                     rec["recipe"], True)))
        return [f for _, f in sorted(out, key=lambda x: x[0])]


def link_latest(link: Path, target: Path) -> bool:
    """Point the symlink `link` at `target` (a cached fit's folder), so a fixed name such as
    bench/runs/generate/diffusion always opens the fit the bench last used. A real file or
    folder at `link` is left alone (returns False)."""
    link = Path(link)
    if link.exists() and not link.is_symlink():
        print(f"note: {link} is a folder of its own, not a link to the fit cache: left as it is")
        return False
    link.parent.mkdir(parents=True, exist_ok=True)
    tmp = link.with_name(f".{link.name}.link.tmp")
    if tmp.is_symlink() or tmp.exists():
        tmp.unlink()
    os.symlink(os.path.relpath(target, link.parent), tmp)
    os.replace(tmp, link)
    return True


def repo_path(text: str) -> Path:
    """A path recorded by the cache ('<repo>/...') as a path in this checkout."""
    return Path(text.replace("<repo>", str(ROOT)))


def dataset_identity(cfg) -> dict:
    """What a fit config's dataset is made of: per shape its annotation (GCs, normalisation,
    mesh reference) and the sha256 of its mesh file's bytes. Instantiating the dataset builds
    missing procedural shapes first, so the identity is the same before and after a fit."""
    from hydra.utils import instantiate

    out = {}
    for ann in instantiate(cfg.data).shapes():
        out[ann.name] = {"annotation": ann.to_dict(),
                         "mesh_sha256": hashlib.sha256(ann.mesh_path.read_bytes()).hexdigest()}
    return out


def train_subprocess(overrides: list[str], run_dir: Path, what: str) -> float:
    """`train.py <overrides>` in its own process on one thread (fits side by side on a
    worker pool), its output in run_dir/train.log; -> wall seconds. SystemExit naming `what`
    and the log if it fails."""
    import subprocess
    import sys
    import time

    t0 = time.perf_counter()
    log = Path(run_dir) / "train.log"
    with open(log, "w") as fh:
        rc = subprocess.call([sys.executable, str(ROOT / "train.py"), *overrides, "threads=1",
                              f"hydra.run.dir={run_dir}"], cwd=ROOT, stdout=fh,
                             stderr=subprocess.STDOUT, env={**os.environ, "OMP_NUM_THREADS": "1"})
    if rc:
        raise SystemExit(f"{what} failed (exit {rc}): see {log}")
    return time.perf_counter() - t0


def cached_run_fit(bench: str, cfg, refit: bool = False, extra: dict | None = None,
                   label: str | None = None) -> Fit:
    """`ngc_gen.app.stages.fit.run_fit(cfg)` through the bench's FitCache: the recipe is the whole
    resolved config (`config_recipe`), the dataset's identity (`dataset_identity`) and
    `extra` (settings of the bench that shape the fit but are not in the config). The fit's
    run_dir is the cache folder (its metrics.json, checkpoints/last.ckpt, meshes/); info holds
    train_s, steps, wall_s (run_fit's wall seconds: preparation, training, scoring) and
    `label` (a name for listings, e.g. `FitCache(bench).entries()`; not part of the key)."""
    recipe = {"config": config_recipe(cfg), "data": dataset_identity(cfg), **(extra or {})}

    def fit(run_dir: Path) -> dict:
        import time

        from omegaconf import open_dict

        from ngc_gen.app.stages.fit import run_fit

        with open_dict(cfg):
            cfg.run_dir = str(run_dir)
        t0 = time.perf_counter()
        m = run_fit(cfg)
        return {"train_s": m["train_s"], "steps": m["steps"],
                "wall_s": time.perf_counter() - t0, "label": label}

    return FitCache(bench).get(recipe, fit, refit=refit)


def cached_stage(cache: FitCache, name: str, cfg, run: Callable, refit: bool = False,
                 link: Path | None = None, leave_out: tuple[str, ...] = ()) -> Fit:
    """A stage's run (`run(cfg)`, e.g. run_shape_latent) through `cache`, keyed by the stage's
    name, its resolved config (less the `leave_out` groups, which it never reads) and the
    dataset's identity; `link` (e.g. bench/runs/generate/shape_latent) points at the run.
    info holds stage_s (the stage's wall seconds) and the name as label."""
    def fit(run_dir: Path) -> dict:
        import time

        from omegaconf import open_dict

        with open_dict(cfg):
            cfg.run_dir = str(run_dir)
        t0 = time.perf_counter()
        run(cfg)
        return {"stage_s": time.perf_counter() - t0, "label": name}

    recipe = {k: v for k, v in config_recipe(cfg).items() if k not in leave_out}
    f = cache.get({"stage": name, "config": recipe, "data": dataset_identity(cfg)}, fit,
                  refit=refit)
    if link is not None:
        link_latest(link, f.run_dir)
    return f


def latest_fit(bench: str, where: dict | None = None, root: Path = FITS) -> Fit:
    """The newest complete fit in another bench's cache whose config has the values of `where`
    (dotted keys: {"trainer.max_steps": 1500}): how a bench reuses a fit another bench trained,
    without importing it. SystemExit with one line naming the make target when there is none."""
    def value(recipe: dict, dotted: str):
        node = recipe.get("config", {})
        for k in dotted.split("."):
            node = node.get(k) if isinstance(node, dict) else None
        return node

    where = where or {}
    fits = [f for f in FitCache(bench, root).entries()
            if all(value(f.recipe, k) == v for k, v in where.items())]
    if not fits:
        want = ", ".join(f"{k}={v}" for k, v in where.items())
        raise SystemExit(f"no {bench} fit in {Path(root) / bench}" + (f" with {want}" if want
                         else "") + f": run `make bench-{bench.replace('_', '-')}` first")
    return fits[-1]


def fresh_clone(rev: str, workdir, prefix: str) -> tuple[str, Path, Path]:
    """This repository at `rev` cloned into a new folder: (commit, folder, clone)."""
    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", rev],
                            check=True, capture_output=True, text=True).stdout.strip()
    work = Path(tempfile.mkdtemp(prefix=prefix, dir=workdir))
    clone = work / "clone"
    subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
    subprocess.run(["git", "-C", str(clone), "checkout", "-q", commit], check=True)
    return commit, work, clone


def make_in(clone: Path, target: str, log_path: Path, env=None) -> float:
    """`make <target>` in `clone`, its output in `log_path`: the wall seconds (exits on failure)."""
    start = time.perf_counter()
    with open(log_path, "w") as log:
        rc = subprocess.run(["make", target], cwd=clone, stdout=log, stderr=subprocess.STDOUT,
                            env=env).returncode
    if rc != 0:
        sys.exit(f"make {target} failed (exit {rc}); see {log_path}")
    return time.perf_counter() - start
