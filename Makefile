# pushbot: the two commands are `make demo` and `make test`; both set up .venv on first use.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.pushbot-installed
PACKAGES := push_core push_ros sim_bridge push_perception push_estimator push_planner push_executor pushbot pushbot_bringup
SETUP_FILES := $(foreach p,$(PACKAGES),src/$(p)/setup.py src/$(p)/setup.cfg)

.PHONY: demo test test-fast venv lint bench constraints clean

demo: $(STAMP)
	$(BIN)/pushbot demo

# The suite on one worker more than the cores (pytest-xdist; tests/conftest.py: one ROS domain
# per worker, tests sharing a module-scoped graph kept on one worker): the graph and CLI tests
# spend much of their time waiting for node processes and DDS discovery, and the extra worker
# fills that time (docs/DEVELOPING.md). PYTEST_WORKERS=0 runs it in one process;
# PYTEST_ARGS adds pytest options (benchmarks/time_tests.py passes its own).
PYTEST_WORKERS ?= $(shell echo $$(( $$(nproc) + 1 )))
PYTEST_ARGS ?=
XDIST := -n $(PYTEST_WORKERS) --dist loadgroup

# The whole suite, as CI runs it; it prints its 30 slowest tests (docs/DEVELOPING.md).
test: $(STAMP)
	$(BIN)/python -m pytest $(XDIST) --durations=30 $(PYTEST_ARGS)

# The fast tier: unit and in-process tests, no node processes or graphs (markers graph, slow).
test-fast: $(STAMP)
	$(BIN)/python -m pytest $(XDIST) -m "not graph and not slow" $(PYTEST_ARGS)

venv: $(STAMP)

$(STAMP): requirements.txt constraints.txt $(SETUP_FILES)
	@$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 11), "pushbot needs Python >= 3.11, found " + sys.version' 
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -r requirements.txt -c constraints.txt
	# gym-pusht (Push-T, `pushbot eval pusht`) without its opencv-python<5 requirement: a second
	# cv2 next to opencv-python-headless 5 breaks both; its other needs are in requirements.txt.
	$(BIN)/python -m pip install --no-deps gym-pusht==0.1.8
	# compat mode: a .pth with each source folder, so modules added later import without
	# reinstalling; no build isolation, so the pinned setuptools of .venv builds them.
	$(BIN)/python -m pip install --no-deps --no-build-isolation --config-settings editable_mode=compat $(foreach p,$(PACKAGES),-e src/$(p))
	touch $(STAMP)

lint: $(STAMP)
	$(BIN)/ruff check .

bench: $(STAMP)
	$(BIN)/python benchmarks/run_all.py

# Refresh the full resolved set after changing requirements.txt.
constraints: $(STAMP)
	{ sed -n '1,2p' constraints.txt; $(BIN)/python -m pip freeze --exclude-editable | grep -v '^torch=='; } > constraints.txt.new
	mv constraints.txt.new constraints.txt

clean:
	rm -rf $(VENV) ros_ws/build ros_ws/install ros_ws/log
