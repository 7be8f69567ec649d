# Two commands for a new user:  `make demo`  and  `make test`.  Both set up first.
# Set-up is idempotent: each stage re-runs only when its inputs changed.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMPS := $(VENV)/.stamps
INTERFACE_FILES := $(shell find interfaces -type f)
export MUJOCO_GL ?= egl
export OPENBLAS_NUM_THREADS ?= 1

.PHONY: setup lint demo test test-fast bench bench-sim bench-walk bench-arm bench-nav bench-idle bench-scenario bench-response bench-locomotion bench-sensors bench-soak bench-camera bench-fetch clean

# Bytecode is written as Python writes it by default, also where PYTHONDONTWRITEBYTECODE is set (many containers, and
# the machines this was measured on). With it set, Python reads .pyc files but writes none: every process compiled the
# project's modules again at each start (~0.09 s of the 0.38 s of CPU /sim's imports take; `make test` starts ~330
# nodes) and each test worker rewrote every test module (pytest's collection: 3.9 s -> 2.1 s). Set-up writes the
# project's (only what changed, ~0.3 s), which the console scripts then read from any shell.
unexport PYTHONDONTWRITEBYTECODE

setup: $(STAMPS)/project
	@$(PY) -m compileall -q sim_bridge robot_models nodes sim_ros sim_client tests benchmarks tools > /dev/null

$(STAMPS)/deps: requirements.txt
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -r requirements.txt
	@mkdir -p $(STAMPS) && touch $@

$(STAMPS)/interfaces: $(STAMPS)/deps $(INTERFACE_FILES) tools/build_interfaces.py
	$(PY) tools/build_interfaces.py
	@touch $@

$(STAMPS)/project: $(STAMPS)/interfaces pyproject.toml package.xml tools/register_ament.py
	$(PY) -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation -e .
	$(PY) tools/register_ament.py
	@touch $@

demo: setup
	$(VENV)/bin/sim-demo

# Two workers per core (at most 8), one test file each at a time (a file's bring-up stays in its worker), the
# longest files first (tests/conftest.py orders them; xdist keeps that order); each worker has a ROS domain of its own.
# The tests wait on sim time, discovery and goals a good part of their wall time. On 2 cores (28 November, /clock at
# 20 Hz) 2 workers took 9:07 (642 s of CPU), 3 took 6:54 (647 s) and 4 took 6:33 (681 s, the README's commands 276 s
# instead of 198 at real time). On 29 November, the README's starts at rtf 3: 3 workers 6:40 (627 s), 4 workers 6:04
# (637 s, the two cores busy 87% of the time). Three workers once failed test_respawn (a restarted server that no
# client reached: Fast DDS's shared-memory port of a killed process, eProsima/Fast-DDS#5053); bringup now restarts a
# node on UDP only. TEST_WORKERS=0 runs everything in one process.
TEST_WORKERS ?= $(shell n=$$(nproc 2>/dev/null || echo 1); echo $$(( 2 * n < 8 ? 2 * n : 8 )))
PYTEST_PARALLEL := $(if $(filter 0,$(TEST_WORKERS)),,-n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder \
	--max-worker-restart 2)

# The lint and type gate (configured in pyproject.toml); `make test` runs it first and stops when it fails.
# Its tools come from requirements.txt with the set-up; mypy checks against the installed project.
# Both run, so one pass shows every finding; the target fails if either found something.
lint: $(STAMPS)/project
	@status=0; \
	echo "ruff check ."; $(VENV)/bin/ruff check . || status=1; \
	echo "mypy"; $(VENV)/bin/mypy || status=1; \
	exit $$status

test: setup lint
	$(PY) -m pytest $(PYTEST_PARALLEL)

test-fast: setup
	$(PY) -m pytest $(PYTEST_PARALLEL) -m "not slow"

bench: bench-sim bench-walk bench-arm bench-nav bench-idle bench-scenario bench-response bench-locomotion bench-sensors bench-camera  ## every benchmark; figures are ratios measured in one run

bench-sim: setup
	$(PY) benchmarks/sim_bench.py

bench-walk: setup
	$(PY) benchmarks/walk_bench.py

bench-locomotion: setup
	$(PY) benchmarks/locomotion_bench.py

bench-arm: setup
	$(PY) benchmarks/arm_bench.py

bench-nav: setup
	$(PY) benchmarks/nav_bench.py

bench-idle: setup
	$(PY) benchmarks/idle_bench.py

bench-scenario: setup
	$(PY) benchmarks/scenario_bench.py

bench-fetch: setup  ## the G1 fetches the box, cube or can over 50 seeded layouts in the core, then 5 of them through ROS
	$(PY) benchmarks/fetch_bench.py --ros 5

clean:
	rm -rf $(VENV) build

bench-response: setup
	$(PY) benchmarks/response_bench.py

bench-sensors: setup
	$(PY) benchmarks/sensors_bench.py

# 10 minutes, 10 client processes against the G1 (not part of `make bench`): RSS, CPU, goals, /joint_states.
bench-soak: setup
	$(PY) benchmarks/soak_bench.py --minutes 10 --clients 10

# The G1 head camera's frames per second (320x240, 640x480, 1280x720) and what rendering at 30 Hz of sim time costs the physics.
bench-camera: setup
	$(PY) benchmarks/camera_bench.py
