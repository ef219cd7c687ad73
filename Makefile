# make demo / make test do all set-up they need on a fresh Debian 12 machine.
SHELL := /bin/bash
VENV := .venv
PY := $(VENV)/bin/python
DEB_PACKAGES := python3-dolfinx python3-gmsh python3-meshio python3-scipy python3-venv \
                libopenblas0-pthread openmpi-bin libegl1 libegl-mesa0
export OMPI_ALLOW_RUN_AS_ROOT := 1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM := 1
export OPENBLAS_NUM_THREADS := 1
export OMP_NUM_THREADS := 1
MPIRUN := mpirun -n 2 --oversubscribe

.PHONY: notebooks setup system demo test test-serial test-mpi test-release lint benchmark release-data compare-releases clean

#: 12 or 13: the Debian release this machine runs (the CI legs write their release data apart)
DEBIAN := $(shell . /etc/os-release 2>/dev/null && echo $$VERSION_ID)

system:
	@missing=$$(for p in $(DEB_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages: $$missing"; \
	  SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq $$missing; \
	fi

# pip must not replace what Debian built dolfinx against (numpy 1.x on Debian 12, 2.x on Debian 13):
# the venv sees the system packages, and pip is constrained to their versions.
SYSTEM_PINNED := numpy scipy meshio mpi4py petsc4py
$(VENV)/.installed: pyproject.toml | system
	/usr/bin/python3 -m venv --system-site-packages $(VENV)
	$(PY) -c 'import importlib.metadata as m; [print(f"{p}=={m.version(p)}") for p in "$(SYSTEM_PINNED)".split()]' \
	  > $(VENV)/constraints.txt
	$(PY) -m pip install -q -c $(VENV)/constraints.txt -e '.[test]'
	touch $@

setup: system $(VENV)/.installed

demo: setup
	$(VENV)/bin/softtissue run examples/isometric.toml --out results/demo

#: The tests compile their kernels with gcc -O0 (model/compat.py, SOFTTISSUE_JIT_CFLAGS): the suite is bound by
#: compiling ~1,800 small-mesh kernels from a cold cache; 14 % less wall time on a cold-cache sample of six modules
#: (346 s -> 297 s). Runs, notebooks opened by hand and benchmarks keep dolfinx's -O2.
TEST_JIT := SOFTTISSUE_JIT_CFLAGS="-O0 -g0"

test-serial: setup
	$(TEST_JIT) $(PY) -m pytest -q -n 2 --durations=25 tests

test-mpi: setup
	$(TEST_JIT) $(MPIRUN) $(PY) -m pytest -q -p no:cacheprovider --durations=15 tests

test: test-serial test-mpi

#: The tests of what differs between dolfinx releases (model/compat.py's paths: meshes and their files, every law
#: assembled and solved, expressions, outputs, the solvers' presets and nested blocks, contact, membranes, verify,
#: a cold JIT cache, MPI), serially (and some on 2 ranks): CI's Debian 13 leg (.ci/run), 592 of 1,909 tests,
#: with the cross-release comparison of five runs and every law's verify references (make release-data). The
#: whole suite on Debian 13: bash .ci/debian13 test.
RELEASE_TESTS := $(addprefix tests/test_,$(addsuffix .py,homogeneous jacobian energies mesh_files meshes \
  gingerbread_mesh fibres polar_inverted parallel results_one_run provenance cli demos nested_jacobian \
  linear_presets scale_check loadstepping line_search petsc_options contact body_contact twin_muscles \
  self_contact membrane membrane_file verify_api verify_element verify_files cold_cache_arguments render \
  render_mesh config_errors mesh_checks admissibility path_following conflicts signals verify_diagnosis \
  verify_speed compile_once parameter_curves calibration reactions_shared))

#: Of these, on 2 ranks: the partition-dependent paths (distributed meshes and their files, outputs, the nested
#: blocks' index sets, contact between bodies, the JIT cache shared by the ranks).
RELEASE_MPI_TESTS := $(addprefix tests/test_,$(addsuffix .py,parallel mesh_files results_one_run cold_cache_arguments \
  body_contact nested_jacobian calibration))

test-release: setup
	$(TEST_JIT) $(PY) -m pytest -q -n 2 --durations=10 $(RELEASE_TESTS)
	$(TEST_JIT) $(MPIRUN) $(PY) -m pytest -q -p no:cacheprovider --durations=10 $(RELEASE_MPI_TESTS)

#: Executed Jupyter notebooks (.ipynb, with their outputs and pictures) of notebooks/*.py in results/notebooks/,
#: which git ignores; installs the extra [notebooks] (jupytext, nbconvert, ipykernel) into .venv first.
#: NOTEBOOK=isometric for one of them; CI=true for their short versions (what the tests run).
NOTEBOOKS := $(filter-out notebooks/_%,$(wildcard notebooks/*.py))
notebooks: setup
	$(PY) -m pip install -q -c $(VENV)/constraints.txt -e '.[notebooks]'
	mkdir -p results/notebooks
	for nb in $(if $(NOTEBOOK),notebooks/$(NOTEBOOK).py,$(NOTEBOOKS)); do \
	  out=results/notebooks/$$(basename $$nb .py).ipynb; echo "$$nb -> $$out"; \
	  $(VENV)/bin/jupytext --to ipynb --execute --run-path notebooks --output $$out $$nb || exit 1; \
	done
	@echo "open them with: .venv/bin/pip install jupyterlab && .venv/bin/jupyter lab results/notebooks"

lint: setup
	$(PY) -m ruff check forms model meshes tests benchmarks notebooks examples
	$(VENV)/bin/lint-imports

# Five runs and the verify references of every law on this release, from inputs shared by both
# CI legs (tests/release_data.py); compare-releases checks debian12/ against debian13/.
release-data: setup
	$(PY) tests/release_data.py results/releases/inputs results/releases/debian$(DEBIAN)

compare-releases: setup
	RELEASE_DATA=results/releases $(PY) -m pytest -q -s -rs tests/test_releases.py

benchmark: setup
	$(PY) benchmarks/assembly.py

clean:
	rm -rf results .pytest_cache
