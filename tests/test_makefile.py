"""The Makefile's install steps: PyTorch stays pinned to its CPU build whichever step a first
install was stopped in (issue 56 §5). `make` runs for real in a copy of the Makefile, with a
stand-in interpreter whose pip only records what it was asked to install."""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# `python3 -m venv DIR` makes DIR/bin/python and a DIR/bin/pip that logs its arguments, one call a
# line, and fails (as a dropped connection or Ctrl-C would) while the file `interrupt` exists.
FAKE_PYTHON = """#!/bin/sh
if [ "$1" = "-m" ] && [ "$2" = "venv" ]; then
  mkdir -p "$3/bin"
  cp "$0" "$3/bin/python"
  cat > "$3/bin/pip" <<'PIP'
#!/bin/sh
echo "$*" >> pip.log
if [ -e interrupt ]; then rm interrupt; exit 130; fi
exit 0
PIP
  chmod +x "$3/bin/pip"
fi
"""


def _make(work: Path, target: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith("MAKE")}
    return subprocess.run(
        ["make", "-s", target, f"PY={work / 'python3'}"], cwd=work, env=env, capture_output=True, text=True
    )


@pytest.fixture
def work(tmp_path):
    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    for name in ("Makefile", "constraints.txt", "pyproject.toml"):
        shutil.copy(ROOT / name, tmp_path / name)
    py = tmp_path / "python3"
    py.write_text(FAKE_PYTHON)
    py.chmod(py.stat().st_mode | stat.S_IEXEC)
    return tmp_path


def _pinned(line: str, constraints: Path) -> bool:
    words = line.split()
    return "-c" in words and (constraints.parent / words[words.index("-c") + 1]).resolve() == constraints.resolve()


def test_the_constraints_pin_the_cpu_build():
    pins = [ln.strip() for ln in (ROOT / "constraints.txt").read_text().splitlines() if ln.strip()[:1].isalpha()]
    assert pins == ["torch==2.13.0"]


@pytest.mark.parametrize("target", ["install-dev", "install"])
def test_an_install_stopped_in_the_torch_step_resumes_pinned(work, target):
    (work / "interrupt").touch()  # the first pip call (PyTorch's) is stopped
    first = _make(work, target)
    assert first.returncode != 0 and (work / ".venv/bin/python").exists()  # the interpreter is there
    second = _make(work, target)
    assert second.returncode == 0, second.stderr
    calls = (work / "pip.log").read_text().splitlines()
    # the stopped torch step, then torch again (its marker was never written), then the project
    assert len(calls) == 3 and calls[0].split()[-1] == calls[1].split()[-1] == "torch" and "-e" in calls[2]
    assert all(_pinned(c, work / "constraints.txt") for c in calls), calls


def test_a_finished_install_is_not_redone(work):
    assert _make(work, "install-dev").returncode == 0
    assert _make(work, "install-dev").returncode == 0
    assert len((work / "pip.log").read_text().splitlines()) == 2
