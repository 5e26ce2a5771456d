# Two commands do everything on a fresh machine:
#   make run    installs into .venv if needed and runs the reference case
#   make test   installs into .venv if needed and runs the test suite
#   make validation   runs the benchmarks of docs/validation.md and redraws its figures
#   make mpi    adds the engine of `masonry run --processes P` to .venv: Debian's MPICH, then
#               mpi4py, PETSc (on the mkl wheel's BLAS, LAPACK and PARDISO) and petsc4py built
#               from source against it
#   make reference    writes the case file's reference again from the case model (masonry
#                     schema): docs/reference/case.md and docs/reference/case.schema.json
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
CASE   ?= cases/wall_0.5MPa.yaml

.PHONY: run test check-cases validation venv lint clean-cache reference mpi

$(BIN)/masonry: pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(BIN)/masonry

venv: $(BIN)/masonry

# The distributed engine (docs/guide/solvers.md): one MPI for everything, Debian's MPICH, under
# mpi4py and PETSc alike (MPICH's wheel, which `make venv` does not install, would be a second
# one). PETSc's source distribution configures against it, without C++ or Fortran, and compiles
# for about three minutes on two cores (the whole install about seven). Its BLAS and LAPACK are
# the `mkl` wheel's that `make venv` installed (sequential, 32-bit integers), with MKL's headers
# from the `mkl-include` wheel of the same version: PETSc then has MKL's PARDISO for the coarse
# level's LU (MKL's cluster PARDISO configures too, but cannot find its MPI wrappers at run time
# under petsc4py). PETSc finds MKL by its libraries' plain names, which the wheel does not ship:
# .venv/mkl links them (and their versioned names, which the libraries load, so that its
# programs find them there).
# Where the venv has no MKL (not x86-64), Debian's LAPACK serves and the coarse LU is PETSc's own.
# The build runs each time (--no-cache-dir): pip's cache does not know the configure options.
# petsc4py is built each time too (some minutes), as its build records where PETSc is.
# Debian's packages are installed when missing (as root).
MPI_DEBS := mpich libmpich-dev liblapack-dev
PETSC_CONFIGURE_OPTIONS ?= --with-cxx=0 --with-fc=0 --with-debugging=0 --with-x=0 COPTFLAGS=-O2
PETSC_VERSION ?= 3.26.1
MKL_DIR := $(abspath $(VENV))/mkl
space := $(subst ,, )
comma := ,
MKL_LIBS := $(patsubst %,$(MKL_DIR)/lib/libmkl_%.so,intel_lp64 sequential core)
MKL_OPTIONS := --with-blaslapack-lib=[$(subst $(space),$(comma),$(strip $(MKL_LIBS)))] \
  --with-blaslapack-include=$(MKL_DIR)/include --with-mkl_pardiso=1

$(VENV)/.mpi-installed: $(BIN)/masonry
	dpkg -s $(MPI_DEBS) >/dev/null 2>&1 || { apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive apt-get install -y -q $(MPI_DEBS); }
	$(BIN)/python -m pip uninstall --quiet -y mpich
	MPICC=mpicc $(BIN)/python -m pip install --quiet --no-binary mpi4py --force-reinstall \
	  --no-deps 'mpi4py>=4'
	rm -rf $(MKL_DIR); options='$(PETSC_CONFIGURE_OPTIONS)'; \
	if ls $(VENV)/lib/libmkl_core.so.* >/dev/null 2>&1; then \
	  mkl=$$($(BIN)/python -c 'import importlib.metadata as m; print(m.version("mkl"))') && \
	  $(BIN)/python -m pip install --quiet --no-deps "mkl-include==$$mkl" && \
	  mkdir -p $(MKL_DIR)/lib && ln -s $(abspath $(VENV))/include $(MKL_DIR)/include && \
	  for f in $(abspath $(VENV))/lib/libmkl_*.so.*; do \
	    b=$$(basename $$f); ln -sf $$f $(MKL_DIR)/lib/$$b; \
	    ln -sf $$f $(MKL_DIR)/lib/$${b%%.so*}.so; done && \
	  options="$$options $(MKL_OPTIONS)" || exit 1; fi; \
	MPICC=mpicc PETSC_CONFIGURE_OPTIONS="$$options" \
	  $(BIN)/python -m pip install --quiet --no-cache-dir --force-reinstall --no-deps \
	  petsc==$(PETSC_VERSION)
	PETSC_DIR=$$($(BIN)/python -c 'import petsc; print(petsc.get_petsc_dir())') PETSC_ARCH= \
	  $(BIN)/python -m pip install --quiet --no-cache-dir --force-reinstall --no-deps \
	  petsc4py==$(PETSC_VERSION)
	$(BIN)/python -c 'from petsc4py import PETSc; from mpi4py import MPI; \
	  print("PETSc", PETSc.Sys.getVersion(), "on", MPI.Get_library_version().splitlines()[0], \
	        "with MKL PARDISO" if PETSc.Sys.hasExternalPackage("mkl_pardiso") else "")'
	touch $@

mpi: $(VENV)/.mpi-installed

run: venv
	$(BIN)/masonry run $(CASE) --overwrite

test: venv
	$(BIN)/python -m pytest -q

check-cases: venv
	$(BIN)/masonry check-cases --overwrite

# The benchmarks of docs/validation.md, their figures redrawn into docs/figures/ and a table of
# measured value, reference, error and run time; VALIDATION_ARGS=--full adds the nave bay.
validation: venv
	nice -n 10 $(BIN)/python scripts/validation.py $(VALIDATION_ARGS)

lint: venv
	$(BIN)/ruff check masonry_nscd tests

reference: venv
	$(BIN)/masonry schema --markdown -o docs/reference/case.md
	$(BIN)/masonry schema --json -o docs/reference/case.schema.json

clean-cache: venv
	$(BIN)/masonry cache-clear
