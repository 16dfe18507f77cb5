# Two commands a newcomer needs: `make demo` and `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
OUT ?= runs/demo

.PHONY: demo test check lint install install-dev clean

# torch is pinned by constraints.txt in every pip step (the CPU wheel, never CUDA packages) and is
# installed first; the step's marker is written only after it, so a first install stopped anywhere
# (even with .venv/bin/python already there) redoes it, still pinned.
PIP := $(BIN)/pip install -q -c constraints.txt

$(VENV)/.torch: constraints.txt
	$(PY) -m venv $(VENV)
	$(PIP) torch
	touch $@

$(VENV)/.installed: $(VENV)/.torch pyproject.toml
	$(PIP) -e ".[live]"
	touch $@

$(VENV)/.installed-dev: $(VENV)/.torch pyproject.toml
	$(PIP) -e ".[dev]"
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

# --durations: CI's log names the 25 slowest tests (CI must stay under 25 min on 2 cores)
test: lint
	$(BIN)/python -m pytest -q -n 2 --dist loadfile --durations=25

clean:
	rm -rf $(VENV) runs .pytest_cache
