# somo-sweep chores. `make help` lists them.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp

.DEFAULT_GOAL := help
.PHONY: help install demo test test-slow lint format bench bench-statics bench-scaling bench-scale bench-engines bench-mujoco bench-warp bench-trial-process bench-robust bench-numerics bench-auto-numerics bench-zero-kpa bench-design bench-fig6-reference bench-active bench-original fig6 fig6-fast fig6-audit fig6-quick fig6-original fig6-ablation fig6-ablation-quick fig3 fig5 fig5-quick palm palm-quick fig7 fig7-quick fig8 fig8-quick diagnose-demo sweep-demo example-gripper example-gripper-pybullet example-design figures clean

help: ## List the targets
	@grep -E '^[a-zA-Z0-9_-]+:.*?## ' $(MAKEFILE_LIST) | awk 'BEGIN {FS = ":.*?## "}; {printf "  make %-20s %s\n", $$1, $$2}'

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[dev]"
	@touch $(STAMP)

install: $(STAMP) ## Create .venv and install somo-sweep with its dev tools

demo: $(STAMP) ## Install, then the main job on a bundled example: 24 grasp trials labelled pinch / power / no grasp, and their figure
	$(BIN)/somo-sweep run studies/pinch_grasp_demo.yaml
	$(BIN)/somo-sweep paper fig6 results/pinch_grasp_demo --out results/pinch_grasp_demo/figures

test: $(STAMP) ## Install, then run the default test suite (one worker per core)
	$(BIN)/python -m pytest -n auto --dist worksteal

test-slow: $(STAMP) ## Run the long physics tests too (one worker per core)
	$(BIN)/python -m pytest -n auto --dist worksteal -m "slow or not slow"

lint: $(STAMP) ## ruff (lint + format check) and mypy
	$(BIN)/ruff check somo_sweep tests benchmarks
	$(BIN)/ruff format --check somo_sweep tests benchmarks
	$(BIN)/mypy

format: $(STAMP) ## Format the code with ruff
	$(BIN)/ruff format somo_sweep tests benchmarks
	$(BIN)/ruff check --fix somo_sweep tests benchmarks

# The benchmarks (benchmarks/, not installed; `python -m benchmarks.NAME --help` for each).
bench: $(STAMP) ## Speed benchmark: grasp steps (Bullet vs Python), one trial, statics, sweep scaling, Dask vs joblib
	$(BIN)/python -m benchmarks.speed

bench-statics: $(STAMP) ## Bench statics: rows, calibrate and diagnose, solved vs dynamic relaxation
	$(BIN)/python -m benchmarks.statics

bench-scaling: $(STAMP) ## Sweep scaling: demo study at 1 and 2 workers, joblib vs Dask in turn, and the quick study's cells
	$(BIN)/python -m benchmarks.scaling

bench-scale: $(STAMP) ## Sweep memory at 2 000 and 20 000 trials, and a resume's start (30-60 min on 2 cores)
	$(BIN)/python -m benchmarks.scale

bench-engines: $(STAMP) ## The engine benchmark: one pinch trial on PyBullet and on MuJoCo side by side, MuJoCo's 4 ms vs 2 ms -> results/figures/engine_speed.json
	$(BIN)/python -m benchmarks.engines --convergence --out results/figures

bench-mujoco: $(STAMP) ## MuJoCo pinch trials with the loop step by step and as data (control tables stepped in C), side by side: CPU per trial and the share inside mj_step -> results/reference/mujoco_step_speed.json
	$(BIN)/python -m benchmarks.mujoco_step --out results/reference

# The GPU benchmark's options (python -m benchmarks.warp_batch --help); a slow check on the CPU:
# make bench-warp BENCH_WARP_ARGS="--device cpu --cells 4 --batch-size 4 --time-limit-s 300 --out results/warp_check"
BENCH_WARP_ARGS ?= --device cuda --time-limit-s 3600
bench-warp: $(STAMP) ## Many worlds in one call: the 150-cell audit on MuJoCo Warp in batches on a GPU (no batch launched after 1 h): steps/s, trials/s, labels vs C MuJoCo -> results/reference/warp_batch.json
	$(BIN)/python -m benchmarks.warp_batch --out results/reference $(BENCH_WARP_ARGS)

bench-trial-process: $(STAMP) ## A sweep's MuJoCo trials with a fork each and with a kept forked process, in turn (64 quick cells, 2 workers): CPU and wall per trial, the ratio
	$(BIN)/python -m benchmarks.trial_process

bench-robust: $(STAMP) ## What robust labels cost: one trial and the quick study, plain before vs robust now (~40 min on 2 idle cores) -> results/reference/robust_cost.json
	$(BIN)/python -m benchmarks.robust_cost --out results/reference

bench-numerics: $(STAMP) ## One pinch trial at the chosen numerics vs the original's, in turn (--compare and more: python -m benchmarks.numerics --help)
	$(BIN)/python -m benchmarks.numerics

bench-auto-numerics: $(STAMP) ## The automatic numerics on a family of pinch fingers vs a 4x finer step
	$(BIN)/python -m benchmarks.auto_numerics

bench-zero-kpa: $(STAMP) ## The 0-kPa blocked-force row on both engines over a step ladder, and with the plate moved (2-3 min)
	$(BIN)/python -m benchmarks.zero_kpa

bench-design: $(STAMP) ## Does the design search pay? The worked example's exhaustive robust grid (7200 MuJoCo runs, about 40 min on 2 shared cores, resumable) against design and random search over 10 seeds -> results/reference/design_bench.json
	nice -n 10 $(BIN)/python -m benchmarks.design_search --jobs 2 --out results/reference

bench-fig6-reference: $(STAMP) ## The robust Fig. 6 reference: every MuJoCo cell with all 4 replicas (11 550 runs, about 20 min on 2 idle cores, resumable) -> results/reference/fig6_robust/
	nice -n 10 $(BIN)/python -m benchmarks.fig6_reference --jobs 2

bench-active: $(STAMP) ## The active sampler replayed against the robust Fig. 6 reference, 10 seeds per configuration (a few minutes, no simulation) -> results/reference/active_sampling.json
	$(BIN)/python -m benchmarks.active_sampling --out results/reference

# The original SoMo code's checkout and the Python of its own environment (benchmarks/original_fig6/README.md).
ORIGINAL_SOMO   ?= ../somo_orig
ORIGINAL_PYTHON ?= ../venv_orig/bin/python
bench-original: $(STAMP) ## Cross-check against the original SoMo code on Fig. 6's 30 headline cells (needs ORIGINAL_SOMO, ORIGINAL_PYTHON; prints the set-up if missing) -> results/original_fig6
	$(BIN)/python -m benchmarks.original_fig6 --somo $(ORIGINAL_SOMO) --original-python $(ORIGINAL_PYTHON)

fig6: $(STAMP) ## Paper Fig. 6: pinch-grasp study, 2310 trials (resumable), figure + smallest all-width pinch DSR
	$(BIN)/somo-sweep run studies/pinch_grasp_dsr.yaml
	$(BIN)/somo-sweep paper fig6 results/pinch_grasp_dsr --out results/figures
	$(BIN)/somo-sweep paper fig6 results/pinch_grasp_dsr --out results/figures --rule paper

fig6-fast: $(STAMP) ## Fig. 6 on MuJoCo (4 ms) with robust labels: 2310 cells sampled actively, trials and 4 replicas where labels are undecided, to 97 % estimated agreement (resumable; about 5 min on 2 cores) -> results/figures/mujoco
	$(BIN)/somo-sweep run studies/pinch_grasp_dsr_mujoco.yaml
	$(BIN)/somo-sweep paper fig6 results/pinch_grasp_dsr_mujoco --out results/figures/mujoco
	$(BIN)/somo-sweep paper fig6 results/pinch_grasp_dsr_mujoco --out results/figures/mujoco --rule paper

fig6-audit: $(STAMP) ## Fig. 6's engine audit: 150 stratified cells on PyBullet and MuJoCo, 4 replicas each (resumable; hours on PyBullet), then the fast figure with the agreement
	$(BIN)/somo-sweep compare-engines studies/pinch_grasp_audit.yaml --out results/fig6_audit
	$(BIN)/somo-sweep paper fig6 results/pinch_grasp_dsr_mujoco --out results/figures/mujoco --audit results/fig6_audit
	$(BIN)/somo-sweep paper fig6 results/pinch_grasp_dsr_mujoco --out results/figures/mujoco --audit results/fig6_audit --rule paper

fig6-quick: $(STAMP) ## Fig. 6 on a 192-trial subset (a few minutes on 2 cores), into results/figures/quick
	$(BIN)/somo-sweep run studies/pinch_grasp_quick.yaml
	$(BIN)/somo-sweep paper fig6 results/pinch_grasp_quick --out results/figures/quick
	$(BIN)/somo-sweep paper fig6 results/pinch_grasp_quick --out results/figures/quick --rule paper

fig6-original: $(STAMP) ## Fig. 6 the original's way at its 0.5 ms: 2310 cells (adaptive, resumable, ~70 min on 2 cores), paper rule, into results/figures/original
	$(BIN)/somo-sweep run studies/pinch_grasp_dsr_original_0p5ms.yaml --adaptive
	$(BIN)/somo-sweep paper fig6 results/pinch_grasp_dsr_original_0p5ms --out results/figures/original --rule paper --max-dsr 0.7

fig6-ablation: $(STAMP) ## Fig. 6 ablation, ours vs the original's choices one factor at a time: 4 simulated configurations x 2310 cells (adaptive, resumable) -> results/reference/fig6_ablation.{csv,md,png}, fig6_compare.png
	$(BIN)/somo-sweep paper fig6-ablation --paper-style --out results/reference

fig6-ablation-quick: $(STAMP) ## The ablation on the 192-cell quick grid (4 simulated configurations, adaptive) -> results/figures/quick
	$(BIN)/somo-sweep paper fig6-ablation --quick --out results/figures/quick

fig3: $(STAMP) ## Paper Fig. 3: blocked force vs pressure, eq. (8)/(9) and fit vs published values
	$(BIN)/somo-sweep paper fig3 --out results/figures

fig5: $(STAMP) ## Paper Fig. 5: gait vs the hardware recording, fingers calibrated on bench values, side weight on 3 cycles (~10 min)
	$(BIN)/somo-sweep paper fig5 --out results/figures

fig5-quick: $(STAMP) ## Fig. 5 on the first gait cycle, no calibration
	$(BIN)/somo-sweep paper fig5 --out results/figures --quick

palm: $(STAMP) ## Palm design study (Sec. V-B): palm height x diameter on the IHM hand (~15 min)
	$(BIN)/somo-sweep run studies/palm_design.yaml --allow-errors
	$(BIN)/somo-sweep paper palm results/palm_design --out results/figures

palm-quick: $(STAMP) ## Palm study on 2 x 2 designs (one per regime), one cycle
	$(BIN)/somo-sweep run studies/palm_design_quick.yaml --overwrite --allow-errors
	$(BIN)/somo-sweep paper palm results/palm_design_quick --out results/figures

fig7: $(STAMP) ## Paper Fig. 7: arm wraps a ball and drops it through a hoop (frames, GIF, half-step check)
	$(BIN)/somo-sweep paper fig7 --out results/figures

fig7-quick: $(STAMP) ## Fig. 7 with small frames, no GIF, no half-step rerun
	$(BIN)/somo-sweep paper fig7 --out results/figures --quick

fig8: $(STAMP) ## Paper Fig. 8: snake with isotropic vs anisotropic friction (10 s each)
	$(BIN)/somo-sweep paper fig8 --out results/figures

fig8-quick: $(STAMP) ## Fig. 8 with 3-s runs
	$(BIN)/somo-sweep paper fig8 --out results/figures --quick

diagnose-demo: $(STAMP) ## Calibrate the bundled bench file, then name what the model misses
	$(BIN)/somo-sweep calibrate studies/tables/planar_finger_bench_2.csv -o results/diagnose_demo/calibrated.yaml
	$(BIN)/somo-sweep diagnose studies/tables/planar_finger_bench_2.csv --model results/diagnose_demo/calibrated.yaml --out results/diagnose_demo

sweep-demo: $(STAMP) ## Run the example study (27 trials) and print its summary
	$(BIN)/somo-sweep run studies/finger_pressure_sweep.yaml --overwrite
	$(BIN)/somo-sweep show results/finger_pressure_sweep

EXAMPLE := results/own_gripper
example-gripper: $(STAMP) ## Your own gripper end to end: bench CSV -> calibrate -> gripper -> robust grasp map over DSR and stiffness (MuJoCo, ~7 min)
	test -f $(EXAMPLE)/study.yaml || $(BIN)/somo-sweep new grasp-study $(EXAMPLE) --finger examples/own_gripper/finger.yaml
	$(BIN)/somo-sweep calibrate examples/own_gripper/finger_bench.csv --model examples/own_gripper/finger.yaml -o $(EXAMPLE)/finger.yaml --report $(EXAMPLE)/calibration
	$(BIN)/somo-sweep run $(EXAMPLE)/study.yaml --out $(EXAMPLE)/grasp_map --jobs 2
	$(BIN)/somo-sweep show $(EXAMPLE)/grasp_map

example-gripper-pybullet: example-gripper ## The same grasp map on PyBullet: 0.25-ms steps, light inertia shaping (about an hour on 2 cores)
	sed -e 's/^name: my_grasp_study/name: my_grasp_study_pybullet/' \
	    -e 's/^  pressure_kpa: 150/  pressure_kpa: 150\n  numerics: {added_inertia_kg_m2: 2.0e-8}/' \
	    -e 's/^simulation: .*/simulation: {engine: pybullet, time_step_s: 2.5e-4}/' $(EXAMPLE)/study.yaml > $(EXAMPLE)/study_pybullet.yaml
	$(BIN)/somo-sweep run $(EXAMPLE)/study_pybullet.yaml --out $(EXAMPLE)/grasp_map_pybullet --jobs 2
	$(BIN)/somo-sweep show $(EXAMPLE)/grasp_map_pybullet

example-design: example-gripper ## Which finger to build: the worked example's distal segment ratio, stiffness and pressure searched for a robust pinch of 20-60 mm boxes (MuJoCo, a few minutes)
	test -f $(EXAMPLE)/design.yaml || cp examples/own_gripper/design.yaml $(EXAMPLE)/design.yaml
	$(BIN)/somo-sweep design $(EXAMPLE)/design.yaml --jobs 2

figures: fig3 fig5 fig6 fig7 fig8 ## Every paper figure (Figs. 3, 5, 6, 7, 8) into results/figures

clean: ## Remove the virtual environment and caches
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache
