# make demo / make test do all set-up they need on a fresh Debian 12 machine.
SHELL := /bin/bash
VENV := .venv
PY := $(VENV)/bin/python
DEB_PACKAGES := python3-dolfinx python3-gmsh python3-meshio python3-scipy python3-venv \
                libopenblas0-pthread openmpi-bin
export OMPI_ALLOW_RUN_AS_ROOT := 1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM := 1
export OPENBLAS_NUM_THREADS := 1
export OMP_NUM_THREADS := 1
MPIRUN := mpirun -n 2 --oversubscribe

.PHONY: setup system demo test test-serial test-mpi lint benchmark clean

system:
	@missing=$$(for p in $(DEB_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages: $$missing"; \
	  SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq $$missing; \
	fi

$(VENV)/.installed: pyproject.toml | system
	/usr/bin/python3 -m venv --system-site-packages $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[test]'
	touch $@

setup: system $(VENV)/.installed

demo: setup
	$(PY) -m model run examples/isometric.toml --out results/demo
	@echo "results and PNG in results/demo (deformed.png, results.xdmf, step_*.vtu, summary.json)"

test-serial: setup
	$(PY) -m pytest -q tests

test-mpi: setup
	$(MPIRUN) $(PY) -m pytest -q -p no:cacheprovider tests

test: test-serial test-mpi

lint: setup
	$(PY) -m ruff check forms model meshes tests benchmarks notebooks examples

benchmark: setup
	$(PY) benchmarks/assembly.py

clean:
	rm -rf results .pytest_cache
