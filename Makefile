# deformesh: the two set-up commands are `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
SAMPLE ?= samples/peanut.csv
OUT    ?= out

.PHONY: demo test lint bench bench-peers install clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

# (bytecode written once: where PYTHONDONTWRITEBYTECODE is set, every run would
# otherwise compile the package again, about 0.1 s)
# (the compiled kernels are built here: a changed .pyx reinstalls)
KERNELS := $(wildcard deformesh_cli/*.pyx deformesh_cli/*.pxd deformesh_cli/*/*.pyx deformesh_cli/*/*.pxd)

$(VENV)/.installed: pyproject.toml setup.py $(KERNELS) | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[all]'
	$(BIN)/python -m compileall -q deformesh_cli
	touch $@

$(VENV)/.installed-test: pyproject.toml $(VENV)/.installed
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@

$(VENV)/.installed-bench: pyproject.toml $(VENV)/.installed
	$(BIN)/python -m pip install --quiet -e '.[bench]'
	touch $@

install: $(VENV)/.installed

demo: $(VENV)/.installed
	@mkdir -p $(OUT)
	$(BIN)/deformesh all $(SAMPLE) -o $(OUT)/demo.vtk --png $(OUT)/demo.png

test: $(VENV)/.installed-test lint
	$(BIN)/python -m pytest -q -n 2 --hypothesis-profile=ci

lint: $(VENV)/.installed-test
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache .hypothesis

bench: $(VENV)/.installed-bench
	$(BIN)/python -m compileall -q deformesh_cli
	$(BIN)/python benchmarks/run_contours.py --repeat 3
	$(BIN)/python benchmarks/run_batch.py --repeat 3
	$(BIN)/python benchmarks/run_corpus.py
	$(BIN)/python benchmarks/run_peers.py --repeat 3 --tools deformesh,triangle --section peers-triangle
	$(BIN)/python benchmarks/run_quality.py --repeat 3
	$(BIN)/python benchmarks/run_moving.py --repeat 3
	$(BIN)/python benchmarks/run_graded.py
	$(BIN)/python benchmarks/run_random.py
	$(BIN)/python benchmarks/run_construct.py
	$(BIN)/python benchmarks/run_construct.py --set corpus
	$(BIN)/python benchmarks/run_circles.py
	$(BIN)/python benchmarks/run_adapt.py
	$(BIN)/python benchmarks/run_thin.py --repeat 3
	$(BIN)/python benchmarks/run_startup.py --repeat 9
	$(BIN)/python benchmarks/run_corpus_processes.py --repeat 3
	$(BIN)/python benchmarks/run_layers.py --repeat 3
	$(BIN)/python benchmarks/run_layers_solver.py
	$(BIN)/python benchmarks/run_quads.py --repeat 3
	$(BIN)/python benchmarks/run_progress.py --repeat 9

# only the side-by-side comparison with Triangle and Gmsh (about 25 minutes)
bench-peers: $(VENV)/.installed-bench
	$(BIN)/python benchmarks/run_peers.py --repeat 3
