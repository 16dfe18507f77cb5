# Two commands a newcomer needs: `make demo` and `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
OUT ?= runs/demo

.PHONY: demo test check lint install install-dev clean

# torch is installed first and pinned, so pip takes the CPU wheel and never pulls CUDA packages.
$(BIN)/python:
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q torch==2.13.0

$(VENV)/.installed: $(BIN)/python pyproject.toml
	$(BIN)/pip install -q -e ".[live]"
	touch $@

$(VENV)/.installed-dev: $(BIN)/python pyproject.toml
	$(BIN)/pip install -q -e ".[dev]"
	touch $@ $(VENV)/.installed

install: $(VENV)/.installed
install-dev: $(VENV)/.installed-dev

demo: $(VENV)/.installed
	$(BIN)/wearnav demo --out $(OUT)

# The house rules (pyproject.toml: [tool.ruff], [tool.mypy]); `make test` runs them first, so CI does.
lint: $(VENV)/.installed-dev
	$(BIN)/ruff check src tests scripts
	$(BIN)/ruff format --check src tests scripts
	$(BIN)/mypy

# The fast inner loop: lint, types and the tests not marked slow.
check: lint
	$(BIN)/python -m pytest -q -n 2 --dist loadfile -m "not slow"

test: lint
	$(BIN)/python -m pytest -q -n 2 --dist loadfile

clean:
	rm -rf $(VENV) runs .pytest_cache
