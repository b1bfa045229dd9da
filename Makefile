# Two entry points for a fresh machine with only Python: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: install demo test bench clean

$(STAMP): pyproject.toml
	bash scripts/system-deps.sh
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[opencl,io,dask,dev,view]'
	# the kernels the default trace and the demo scene need, compiled once (a progress bar)
	$(VENV)/bin/flowkit compile default examples/hotroom_scene.toml
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/flowkit demo

# on the machine's cores, at most 4 (each worker compiles the kernels its tests meet first; the
# numba cache on disk is shared, so a kernel one worker compiled, the others load)
test: $(STAMP)
	$(PY) -m pytest -q -n auto --maxprocesses 4

# Peers side by side (VTK, streamtracer, scipy); each script prints its own table and ratios.
BENCHES := bench_trace bench_opencl bench_render bench_styles bench_scene bench_distributed lines_io
bench: $(STAMP)
	$(PY) -m pip install --quiet -e '.[bench]'
	for b in $(BENCHES); do $(PY) benchmarks/$$b.py || exit 1; done

clean:
	rm -rf $(VENV) build dist *.egg-info
