# Two commands do all set-up on a fresh machine:
#   make run   - create .venv if missing, install the pinned set, run the main job: fast squats end to end on
#                the simulated robot (plan, PyBullet physics, record, report)
#   make test  - create .venv if missing, run the whole test suite (what CI runs through .ci/run)
SHELL := /bin/bash
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
PY := $(VENV)/bin/python
PACKAGES := rh5_msgs_py rh5_hyrodyn_mapper rh5_planner rh5_joint_stabilizer rh5_bringup
STAMP := $(VENV)/.installed
PYTEST_ARGS ?=

.PHONY: run test lint venv lock clean

run: $(STAMP)
	$(VENV)/bin/rh5 experiment fast_squats

test: $(STAMP)
	$(PY) -m pytest $(PYTEST_ARGS)

lint: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .

venv: $(STAMP)

INTERFACES := $(wildcard interfaces/*/CMakeLists.txt interfaces/*/package.xml interfaces/*/*/*.msg interfaces/*/*/*.srv interfaces/*/*/*.action)

# The stamp depends on everything that decides what is installed, so an edited lock re-installs.
# tools/build_interfaces.py then builds the interface packages no wheel provides (interfaces/README.md).
$(STAMP): constraints.txt requirements.txt tools/build_interfaces.py $(INTERFACES) $(foreach p,$(PACKAGES),$(p)/setup.py $(p)/package.xml) $(wildcard */*/*/*.c */*/*/*/*.c */*/*/*.h */*/*/*/*.h)
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	@touch $(VENV)/COLCON_IGNORE  # keep colcon from crawling the venv's share/*/package.xml
	$(PY) -m pip install --quiet --disable-pip-version-check -c constraints.txt -r requirements.txt
	$(PY) tools/build_interfaces.py
	$(PY) -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation --use-pep517 --config-settings editable_mode=compat $(foreach p,$(PACKAGES),-e ./$(p))
	@touch $(STAMP)

# Re-resolve the lock from requirements.txt in a scratch venv (review the diff before committing).
lock:
	rm -rf .lock-venv && $(PYTHON) -m venv .lock-venv
	.lock-venv/bin/pip install --quiet -c ../shared/design/crocoddyl-constraints.txt -r requirements.txt
	.lock-venv/bin/python tools/write_lock.py .lock-venv > constraints.txt
	rm -rf .lock-venv

clean:
	rm -rf $(VENV) build install log .ros .pytest_cache
