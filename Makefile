# Two commands do everything on a fresh machine:
#   make run    installs into .venv if needed and runs the reference case
#   make test   installs into .venv if needed and runs the test suite
#   make validation   runs the benchmarks of docs/validation.md and redraws its figures
#   make reference    writes the case file's reference again from the case model (masonry
#                     schema): docs/reference/case.md and docs/reference/case.schema.json
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
CASE   ?= cases/wall_0.5MPa.yaml

.PHONY: run test check-cases validation venv lint clean-cache reference

$(BIN)/masonry: pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(BIN)/masonry

venv: $(BIN)/masonry

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
