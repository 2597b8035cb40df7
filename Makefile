# Two commands do everything on a fresh machine:
#   make demo   -- create the environment and run the main job on built-in defaults
#   make test   -- create the environment (with Blender and the test tools) and run the tests
PYTHON ?= python3.11
VENV ?= .venv
BIN := $(VENV)/bin
# The CPU build of torch; a bare "torch" request would pull several GB of CUDA wheels.
TORCH_SPEC ?= torch==2.13.0
DEMO_OUT ?= demo-output

.PHONY: demo test lint env env-test system-deps bench clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

env: $(BIN)/python
	$(BIN)/pip install --quiet "$(TORCH_SPEC)"
	$(BIN)/pip install --quiet -e ".[dask,segment,agent,optimise,study]"

env-test: $(BIN)/python system-deps
	$(BIN)/pip install --quiet "$(TORCH_SPEC)"
	$(BIN)/pip install --quiet -e ".[dask,segment,blender,agent,optimise,study,test]"
	# The reference implementation, for parity tests and benchmarks only (its own pins would pull CUDA torch).
	$(BIN)/pip install --quiet --no-deps granatpy==0.1.3

system-deps:
	@sh scripts/install-system-deps.sh

demo: env
	$(BIN)/platesynth demo --out $(DEMO_OUT) --model models/plaque12

test: env-test
	$(BIN)/python -m pytest -q

# ruff's rules and exceptions are in pyproject.toml ([tool.ruff])
lint: env-test
	$(BIN)/ruff check

bench: env-test
	$(BIN)/python benchmarks/run_all.py

clean:
	rm -rf $(VENV) $(DEMO_OUT) .pytest_cache
