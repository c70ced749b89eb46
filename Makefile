# Two commands for a fresh machine: `make demo` and `make test`. Both create .venv when
# missing, install the pinned CPU torch first (a bare `torch` requirement would pull a
# multi-GB CUDA build), then the package with all its extras.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp
OUT ?= out
TORCH_PIN := torch==2.13.0
# The LEAP hand's model (ias_gym.sim.leap_hand) comes from MuJoCo Playground's wheel, which
# is installed without its dependencies (jax, brax, warp): the package reads only its MJCF.
PLAYGROUND_PIN := playground==0.2.0

export MUJOCO_GL ?= egl
export PYOPENGL_PLATFORM ?= egl

.PHONY: setup demo test test-perturbed lint docs browser-check bench clean

$(STAMP): pyproject.toml Makefile
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet $(TORCH_PIN)
	$(BIN)/python -m pip install --quiet -e '.[all]'
	$(BIN)/python -m pip install --quiet --no-deps $(PLAYGROUND_PIN)
	touch $(STAMP)

setup: $(STAMP)

demo: setup
	$(BIN)/ias-gym figure wrench-intensities --out $(OUT) --overwrite
	$(BIN)/ias-gym figure control-error --out $(OUT) --overwrite
	$(BIN)/ias-gym evaluate --env IAS-PenSlide-v0 --policy expert --episodes 10 --video $(OUT)/pen_slide_expert.mp4 --overwrite
	$(BIN)/ias-gym evaluate --env IAS-PenRotate-v0 --policy expert --episodes 10 --video $(OUT)/pen_rotate_expert.mp4 --overwrite
	$(BIN)/ias-gym evaluate --env IAS-PenSlide-v0 --policy random --episodes 10
	$(BIN)/ias-gym evaluate --env IAS-GloveGrasp-v0 --policy teleop --episodes 3 --video $(OUT)/glove_grasp_teleop.mp4 --overwrite
	$(BIN)/ias-gym glove-bench --interface virtual --rate 1000 --seconds 3
	$(BIN)/ias-gym skills transfer --id 2 --hand all --method gt
	$(BIN)/ias-gym assist demo --video $(OUT)/assist.mp4 --overwrite
	$(MAKE) $(OUT)/library.db
	$(BIN)/ias-gym assist demo --db $(OUT)/library.db --impairment stops:at=0.4 --skill tilt_left \
		--person alice --assistant observation --video $(OUT)/assist_stops.mp4 --overwrite
	@echo "make demo: figures, videos and the expert's scores are in $(OUT)/"

# The assistant's skill library: 8 persons of the population, every skill twice (about a
# minute; made once, `assist library` adds to an existing file).
$(OUT)/library.db: | setup
	$(BIN)/ias-gym assist library --db $@ --population 8 --population-seed 61

lint: setup
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy
	$(BIN)/lint-imports  # the layers and contracts of [tool.importlinter] in pyproject.toml

# Every core for the tests that only compute (a file's tests stay on one worker, so its
# fixtures are built once), then the real-time CAN-bus tests alone (pyproject's markers),
# then the docs site and its check in a headless Chromium (skipped, saying why, without one).
test: lint
	$(BIN)/python -m pytest -q -n auto --dist loadfile -m "not realtime and not browser"
	$(BIN)/python -m pytest -q -m realtime
	$(MAKE) browser-check

# The documentation site, warnings as errors, into docs/_build/html. conf.py first writes
# the env pages (from the env docstrings), the API pages and the results tables (from the
# result JSON files); the env pictures are committed (docs/_scripts/render_env_images.py).
docs: setup
	$(BIN)/python -m sphinx -W --keep-going -q -b html docs docs/_build/html

APT_CHROMIUM := DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium

# The built site in headless Chromium (pyproject's browser marker). Installs Debian's
# chromium where it can (root and apt-get); without it the tests are skipped with the reason.
browser-check: docs
	@command -v chromium >/dev/null 2>&1 || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1 \
		&& { $(APT_CHROMIUM) || { apt-get update -qq && $(APT_CHROMIUM); }; } >/dev/null 2>&1; } \
		|| echo "make browser-check: chromium could not be installed; the browser tests are skipped"
	$(BIN)/python -m pytest -q -rs -m browser tests/test_docs_browser.py

# The closed-loop tests once more (pyproject's closed_loop marker) as another machine would
# run them: every start moved by ~1e-9 (IAS_GYM_PERTURB_SEED, a new one each run unless
# given) and the glove calibrations trained under another seed (IAS_GYM_CALIBRATION_SEED,
# 1-3 from it; cached beside the default ones). The seeds are printed: rerun a failure with
# `make test-perturbed PERTURB_SEED=... CALIBRATION_SEED=...`.
ifndef PERTURB_SEED
PERTURB_SEED := $(shell date +%s)
endif
ifndef CALIBRATION_SEED
CALIBRATION_SEED := $(shell echo $$(( 1 + $(PERTURB_SEED) % 3 )))
endif
test-perturbed: setup
	@echo "make test-perturbed PERTURB_SEED=$(PERTURB_SEED) CALIBRATION_SEED=$(CALIBRATION_SEED)"
	IAS_GYM_PERTURB_SEED=$(PERTURB_SEED) IAS_GYM_CALIBRATION_SEED=$(CALIBRATION_SEED) \
		$(BIN)/python -m pytest -q -n auto --dist loadfile -m "closed_loop and not realtime"

bench: setup
	$(BIN)/python bench/run_all.py --out docs/benchmarks --overwrite

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache .mypy_cache .ruff_cache .import_linter_cache \
		docs/_build docs/_generated docs/api
