# One entry point for people and CI. Everything installs into .venv from pinned versions.
SHELL := /bin/bash
.SHELLFLAGS := -o pipefail -c
PYTHON ?= $(shell command -v python3.11 || command -v python3)
# This machine's pip configuration warns about missing local indexes; hide only those lines.
QUIET_PIP := { grep -v "^WARNING: Location" || true; }
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# pytest-xdist workers for make test (tests/conftest.py gives each its own ROS domains)
TEST_WORKERS ?= 2
PACKAGES := ros2_ws/src/excavation_common ros2_ws/src/ant_controller ros2_ws/src/blueprint_server ros2_ws/src/excavation_sim ros2_ws/src/overhead_localizer ros2_ws/src/terrain_mapper ros2_ws/src/blade_driver ros2_ws/src/team_supervisor ros2_ws/src/drive_executor ros2_ws/src/team_tick ros2_ws/src/excavation_bags ros2_ws/src/excavation_bringup ros2_ws/src/excavation_field ros2_ws/src/dome_emulator evolution
DEMO_OUT ?= demo_out
# The test suite runs in a network namespace with only loopback where unshare works (CI runs
# as root), which also proves that nothing in it talks to the outside.
NETNS := $(shell unshare -n true 2>/dev/null && echo "unshare -n")

.PHONY: setup lint test test-system test-pending demo bench soak params clean

$(STAMP): requirements.txt $(addsuffix /setup.py,$(filter ros2_ws/%,$(PACKAGES))) evolution/pyproject.toml
	$(PYTHON) tools/build_interfaces.py --check
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -r requirements.txt 2>&1 | $(QUIET_PIP)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check --no-deps $(addprefix -e ,$(PACKAGES)) 2>&1 | $(QUIET_PIP)
	$(BIN)/python -c "import rclpy, numba, excavation_common, ant_controller, blueprint_server, excavation_sim, blade_driver, team_supervisor, drive_executor, ant_evolution, overhead_localizer, terrain_mapper, excavation_bags, team_tick, excavation_bringup, excavation_field, dome_emulator"
	touch $(STAMP)

# The workspace's interface packages (ament_cmake: .msg files), generated and compiled into
# the venv after every install (tools/build_interfaces.py says why and how).
INTERFACES := $(VENV)/.interfaces
INTERFACE_FILES := $(shell grep -l '<build_type>ament_cmake</build_type>' ros2_ws/src/*/package.xml | xargs -r -n1 dirname | xargs -r -I{} find {} -type f)
$(INTERFACES): $(STAMP) tools/build_interfaces.py $(INTERFACE_FILES)
	$(BIN)/python tools/build_interfaces.py
	touch $(INTERFACES)

setup: $(STAMP) $(INTERFACES)

lint: setup
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/lint-imports

# make test: the suite without the whole-system runs (marker `system`: make test-system), on
# TEST_WORKERS workers (every `serial` test is a system test, so it has no serial pass).
# make test-system runs its parallel part, then its `serial` tests alone. pytest exits 5
# when a marker selects no test. $(1) is the part's marker expression.
FAST := not pending and not system
SYSTEM := system and not pending
# --durations=25: the slowest tests, so that everyone sees where the time goes.
PYTEST := $(BIN)/python -m pytest -q --durations=25
# --dist loadgroup: tests that must not overlap (two local Ray instances) share an xdist_group.
parallel_of = { $(PYTEST) -n $(TEST_WORKERS) --dist loadgroup -m "$(1) and not serial" tests ros2_ws/src || [ $$? -eq 5 ]; }
tests_of = $(call parallel_of,$(1)) && { $(PYTEST) -m "$(1) and serial" tests || [ $$? -eq 5 ]; }

# The kernels compile (numba's cache, kept in ~/.cache between runs and between make test
# and make test-system) while lint runs.
WARMUP_BESIDE_LINT := $(BIN)/python -m ant_evolution.warmup & warm=$$!; $(MAKE) --no-print-directory lint; lint=$$?; wait $$warm && exit $$lint

test: setup
	$(WARMUP_BESIDE_LINT)
ifeq ($(NETNS),)
	$(call parallel_of,$(FAST))
else
	unshare -n sh -c 'ip link set lo up 2>/dev/null; $(call parallel_of,$(FAST))'
endif

# The dome bring-up, the fault matrix and the short soak: long wall-clock runs of the whole
# node suite (about 10 minutes on 2 cores). .ci/run runs them after make test.
test-system: setup
	$(BIN)/python -m ant_evolution.warmup
ifeq ($(NETNS),)
	$(call tests_of,$(SYSTEM))
else
	unshare -n sh -c 'ip link set lo up 2>/dev/null; $(call tests_of,$(SYSTEM))'
endif

# Integration tests marked pending (docs/reliability.md, "Pending").
test-pending: setup
	$(BIN)/python -m pytest -q -m pending tests || [ $$? -eq 5 ]  # 5: none pending

# The demo: the hand-coded baseline, a short evolution (progress bar; about two minutes on
# two cores), the shipped evolved genome with terrain snapshots, and the same genome's
# scenario 0 offline (ant-eval) and through the ROS nodes (ant-trial): the two agree.
demo: setup
	$(BIN)/python -m ant_evolution.warmup
	$(BIN)/ant-eval --hand-coded --robots 4 --scenarios 100 --seed 0 --snapshots $(DEMO_OUT)/hand_coded
	rm -rf $(DEMO_OUT)/evolve
	$(BIN)/ant-evolve --out $(DEMO_OUT)/evolve --population 40 --generations 25 --scenarios 20 --seed 0
	$(BIN)/ant-eval --genome genomes/best.json --robots 4 --depth 1 --scenarios 100 --seed 0 --snapshots $(DEMO_OUT)/evolved
	@echo "Terrain snapshots: $(DEMO_OUT)/hand_coded/strip.png $(DEMO_OUT)/evolved/strip.png"
	@echo "Short evolution: $(DEMO_OUT)/evolve/fitness.png, $(DEMO_OUT)/evolve/best.json"
	$(BIN)/ant-eval --genome genomes/best.json --robots 4 --depth 1 --scenarios 1 --seed 0 --json > $(DEMO_OUT)/offline.json
	ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST $(BIN)/ant-trial --genome genomes/best.json --robots 4 --blueprint default:1 --steps 300 --seed 0 --json > $(DEMO_OUT)/trial.json
	@$(BIN)/python -c 'import json, sys; a = json.load(open(sys.argv[1]))["mean"]; b = json.load(open(sys.argv[2]))["fitness"]; v = "identical" if a == b else "DIFFERENT"; print(f"shipped genome, 4 robots, scenario 0, 300 ticks: ant-eval (offline) {a:.6f} | ant-trial (ROS nodes, blade drivers) {b:.6f} | {v}")' $(DEMO_OUT)/offline.json $(DEMO_OUT)/trial.json

bench: setup
	$(BIN)/ant-bench --write docs/benchmarks.md
	$(BIN)/ant-perception-bench --write docs/benchmarks.md --doc docs/perception.md
	$(BIN)/python -m excavation_field.field_bench bench --write docs/benchmarks.md
	ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST $(BIN)/python -m excavation_bringup.estop_bench --write docs/benchmarks.md

# The soak (docs/benchmarks.md, "Soak"; not part of make test): 4 robots, 10,000 ticks, full
# perception, every node its own process; fails on memory growth or a missed tick.
SOAK_STEPS ?= 10000
soak: setup
	ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST nice -n 10 $(BIN)/ant-soak --robots 4 --steps $(SOAK_STEPS) --perception full --json soak.json --plot docs/figures/soak_memory.png

# The nodes' parameter files (ros2_ws/src/*/config/*.yaml) and the parameter tables of
# docs/interfaces.md, regenerated from the parameter dataclasses through the registry of node
# kinds (excavation_bringup.kinds); tests/test_node_params.py fails while they are stale.
params: setup
	$(BIN)/python -m excavation_bringup.generate

clean:
	rm -rf $(VENV) ros2_ws/build ros2_ws/install ros2_ws/log $(DEMO_OUT)
