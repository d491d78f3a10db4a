# skitter: `make demo` sets up and runs the main job; `make test` sets up and runs the tests and the lint.
# Both create .venv if it is missing and install what they need, once (a stamp file records the install).

PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.skitter-installed
# the library versions to install (constraints.txt: those the leaderboard's rows ran on); CONSTRAINTS= for the
# newest versions pyproject.toml admits
CONSTRAINTS ?= constraints.txt
export MUJOCO_GL ?= egl

# demo budget: PPO on RoachWalk for DEMO_STEPS environment steps (the batched env on both cores), then 10 evaluation
# episodes each of the trained policy and the tripod gait. Each demo makes a new run
# folder and a new results folder; nothing earlier is replaced.
DEMO_STEPS ?= 500000
DEMO_EPISODES ?= 10
DEMO_ID := demo-$(shell date +%Y%m%d-%H%M%S)

.PHONY: setup test test-slow lint demo bench leaderboard leaderboard-table cpg-experiments clean

$(STAMP): pyproject.toml $(CONSTRAINTS)
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet torch==2.13.0
	$(BIN)/python -m pip install --quiet $(if $(CONSTRAINTS),-c $(CONSTRAINTS)) -e '.[dev]'
	touch $(STAMP)

setup: $(STAMP)

lint: setup
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/lint-imports --no-cache

# slow cases (marked) are covered by the calibration matrix benchmark; `make test-slow` runs them too. Two workers
# on two cores, each with one BLAS/OpenMP thread: a worker's small least-squares problems on OpenBLAS's own threads
# fight the other worker for the cores (the suite took 618 s against 534 s, beside a training job, 2026-12-04)
ONE_THREAD = OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1
test: lint
	$(ONE_THREAD) $(BIN)/python -m pytest -n 2 --dist loadgroup -q -m "not slow"

test-slow: setup
	$(ONE_THREAD) $(BIN)/python -m pytest -n 2 --dist loadgroup -q -m slow

demo: setup
	$(BIN)/python train.py --env skitter/RoachWalk-v4 --algo ppo --timesteps $(DEMO_STEPS) --seed 0 --run-name $(DEMO_ID)
	$(BIN)/python evaluate.py --env skitter/RoachWalk-v4 --policy tripod --policy runs/$(DEMO_ID)/model.zip \
		--episodes $(DEMO_EPISODES) --seed 1000 --out results/$(DEMO_ID)

# the leaderboard (agents/leaderboard.py): PPO, plain and as a residual on the reference, on each robot's walk and
# turn, the xJüs's rough ground and each robot's soccer academy (in the commands mode, against the scripted player),
# and each robot's one-a-side self-play (PPO alone, 2M steps, rated against the scripted team), 3 seeds, an hour of
# 2 cores a row as env steps (PPO's throughput with train.py on a 2-core host, 2026-11-29: roach
# 1,140, Bioloid 2,100, xJüs 3,000 steps/s; XjusRough 8% slower than XjusWalk, 2026-11-30; PPO on each academy in
# the commands mode trained at 0.71, 0.72 and 0.73 of its walk's speed over 61,440 steps each, 2026-11-30; but a
# whole XjusGoToBall-v2 row trains at 1,260 steps/s, 0.42, on one core's worth, so its 7M steps take 95 minutes,
# 2026-12-01; the academy's entries now step 16 envs to gain speed, docs/training.md), about 96 hours in all, more
# for the academy (each row is also judged on its policy after an hour of training); rows already done are kept, a
# killed row resumes;
# LEADERBOARD_TASKS, LEADERBOARD_SEEDS and LEADERBOARD_ALGOS pick rows; works in results/leaderboard/, keeps the
# finished rows' records in docs/results/records/ (commit them: a fresh checkout then skips those rows) and writes
# docs/results.md
LEADERBOARD_ACADEMY = skitter/RoachGoToBall-v5 skitter/RoachScoreEmptyGoal-v4 skitter/RoachScoreVsKeeper-v3 \
	skitter/XjusGoToBall-v3 skitter/XjusScoreEmptyGoal-v2 skitter/XjusScoreVsKeeper-v1 \
	skitter/BioloidGoToBall-v4 skitter/BioloidScoreEmptyGoal-v3 skitter/BioloidScoreVsKeeper-v2
# self-play (one a side, rated against the scripted team) trains with ppo alone: the plan skips its +residual rows
LEADERBOARD_SOCCER = soccer/roach soccer/xjus soccer/bioloid
LEADERBOARD_ALL = skitter/RoachWalk-v4 skitter/XjusWalk-v1 skitter/BioloidWalk-v2 skitter/RoachTurn-v5 \
	skitter/XjusTurn-v2 skitter/BioloidTurn-v5 skitter/XjusRough-v1 $(LEADERBOARD_ACADEMY) $(LEADERBOARD_SOCCER)
LEADERBOARD_TASKS ?= $(LEADERBOARD_ALL)
LEADERBOARD_STEPS ?= skitter/RoachWalk-v4=4000000 skitter/XjusWalk-v1=10000000 skitter/BioloidWalk-v2=7000000 \
	skitter/RoachTurn-v5=4000000 skitter/XjusTurn-v2=10000000 skitter/BioloidTurn-v5=7000000 \
	skitter/XjusRough-v1=9000000 \
	skitter/RoachGoToBall-v5=3000000 skitter/RoachScoreEmptyGoal-v4=3000000 skitter/RoachScoreVsKeeper-v3=3000000 \
	skitter/XjusGoToBall-v3=7000000 skitter/XjusScoreEmptyGoal-v2=7000000 skitter/XjusScoreVsKeeper-v1=7000000 \
	skitter/BioloidGoToBall-v4=5000000 skitter/BioloidScoreEmptyGoal-v3=5000000 \
	skitter/BioloidScoreVsKeeper-v2=5000000 soccer/roach=2000000 soccer/xjus=2000000 soccer/bioloid=2000000
LEADERBOARD_SEEDS ?= 0 1 2
LEADERBOARD_ALGOS_ALL = ppo ppo+residual
LEADERBOARD_ALGOS ?= $(LEADERBOARD_ALGOS_ALL)
# the Bioloid's matches last 600 s (half a Four-Legged League match): in 60 s the scripted team scored no goal
# against the random one in any of 20 matches (0-20-0, 2026-12-01), in 600 s it won all 20 (2026-12-02)
LEADERBOARD_MATCHES ?= soccer/bioloid=600
LEADERBOARD_PLAN = --timesteps $(LEADERBOARD_STEPS) \
	$(if $(LEADERBOARD_MATCHES),--match-seconds $(LEADERBOARD_MATCHES)) \
	--episodes 20 --eval-seed 1000 --out results/leaderboard --records docs/results/records
leaderboard: setup
	$(BIN)/python -m agents.leaderboard --tasks $(LEADERBOARD_TASKS) --seeds $(LEADERBOARD_SEEDS) \
		--algos $(LEADERBOARD_ALGOS) $(LEADERBOARD_PLAN) --videos
	$(MAKE) leaderboard-table
# docs/results.md: the table of the whole plan (every robot's walk, turn, academy and self-play, the
# rough ground, seeds 0-2),
# from the rows done so far, even after a run of fewer tasks or seeds (LEADERBOARD_TASKS=..., LEADERBOARD_SEEDS=...);
# trains nothing but the tasks' reference and random baselines
leaderboard-table: setup
	$(BIN)/python -m agents.leaderboard --tasks $(LEADERBOARD_ALL) --seeds 0 1 2 --algos $(LEADERBOARD_ALGOS_ALL) \
		$(LEADERBOARD_PLAN) --table-only \
		--docs docs/results.md

bench: setup
	$(BIN)/python -m benchmarks.env_speed
	$(BIN)/python -m benchmarks.batch_speed
	$(BIN)/python -m benchmarks.train_speed
	$(BIN)/python -m benchmarks.realtime
	$(BIN)/python -m benchmarks.speed_vs_frequency
	$(BIN)/python -m benchmarks.turn_table
	$(BIN)/python -m benchmarks.model_scan
	$(BIN)/python -m benchmarks.calibrate_speed
	$(BIN)/python -m benchmarks.calibration_matrix --robots roach motor servo --workers 2 --minutes 100
	$(BIN)/python -m benchmarks.xjus_speed
	$(BIN)/python -m benchmarks.spine_study
	$(BIN)/python -m benchmarks.bioloid_speed
	$(BIN)/python -m benchmarks.bioloid_figure30
	$(BIN)/python -m benchmarks.bioloid_figure30 --knee-wedge
	$(BIN)/python -m benchmarks.bioloid_static
	$(BIN)/python -m benchmarks.gait_maps
	$(BIN)/python -m benchmarks.soccer_api
	$(BIN)/python -m benchmarks.soccer_speed
	$(BIN)/python -m benchmarks.soccer_dm_control
	$(BIN)/python -m benchmarks.soccer_stability
	$(BIN)/python -m benchmarks.soccer_scripted
	$(BIN)/python -m benchmarks.ground_rules
	$(BIN)/python -m benchmarks.bioloid_cpg_experiments

# the report's CPG experiments 5 and 6 with its PSO at its scale (about 50 minutes each on 2 cores; each resumes from
# its checkpoint when run again), then their summary (make bench summarizes what the run folders hold)
cpg-experiments: setup
	$(BIN)/python -m agents.optimize --config agents/bioloid/optimize/experiment5.json --optimizer pso \
		--iterations 240 --particles 50 --seed 0 --out runs/optimize/experiment5__pso__0
	$(BIN)/python -m agents.optimize --config agents/bioloid/optimize/experiment6.json --optimizer pso \
		--iterations 240 --particles 50 --seed 0 --out runs/optimize/experiment6__pso__0
	$(BIN)/python -m benchmarks.bioloid_cpg_experiments

clean:
	rm -rf $(VENV) *.egg-info .pytest_cache .ruff_cache
