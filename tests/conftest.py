import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from wearnav.errors import WearnavError
from wearnav.recording import DeviceStream, Fixes, Recording, Trajectory
from wearnav.simulate import simulate_dataset

ROOT = Path(__file__).resolve().parents[1]
# WEARNAV_DATA points elsewhere, e.g. from a git worktree that is not beside shared/.
SHARED_DATA = Path(os.environ.get("WEARNAV_DATA") or ROOT / ".." / "shared" / "data").resolve()
# IPIN 2023 walks for a radio map of the venue (floors 0, -1, -2, their barometers giving the floor
# levels) and a walk of the same routes held out from it (tests of a user's own Wi-Fi, issue 60 §3)
IPIN_LOGS = "ipin2023_track3/01 Logfiles/01 IPIN2023_T3_TrainingTrials (training)"
IPIN_SURVEY = (
    "IPIN2023_T3_TrainingTrial51_repetition01.mat",
    "IPIN2023_T3_TrainingTrial51_repetition02.txt.xz",
    "IPIN2023_T3_TrainingTrial52_repetition02.mat",
)
IPIN_HELD_OUT = "IPIN2023_T3_TrainingTrial52_repetition01.txt.xz"


def pytest_configure(config):
    """Under pytest-xdist (`make test`: two workers on two cores) each worker runs torch on one
    thread: two workers' thread pools otherwise spin-wait against each other (4–8× slower), and the
    tests that time the live tracker flake. Processes a test starts keep their own setting (the
    executor's test checks that it sets one thread itself)."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        import torch

        torch.set_num_threads(1)


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The public recordings beside the project (CI has them there too)."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real data not found at {SHARED_DATA}")
    return SHARED_DATA


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory):
    """``tiny_dataset(seed, dest=None)``: what ``simulate_dataset("tiny", dest, seed=seed)`` writes,
    simulated once per test process and seed and copied to ``dest`` (a new folder where None);
    returns ``dest``. One simulation costs ~10 s on 2 cores, a copy of its ~15 MB well under one."""
    made: dict[int, Path] = {}

    def copy(seed: int, dest: Path | None = None) -> Path:
        if seed not in made:
            made[seed] = tmp_path_factory.mktemp(f"tiny-seed{seed}") / "tiny"
            simulate_dataset("tiny", made[seed], seed=seed, progress=False)
        dest = dest or tmp_path_factory.mktemp("tiny") / "tiny"
        shutil.copytree(made[seed], dest)
        return dest

    return copy


def make_stream(n=200, rate=100.0, t0=0.0, seed=0, gyro=True, quat=True, worn=False):
    rng = np.random.default_rng(seed)
    t = t0 + np.arange(n) / rate
    acc = np.tile([0.0, 0.0, 9.81], (n, 1)) + 0.1 * rng.standard_normal((n, 3))
    return DeviceStream(
        t=t,
        acc=acc,
        gyro=0.05 * rng.standard_normal((n, 3)) if gyro else None,
        quat=np.tile([1.0, 0, 0, 0], (n, 1)) if quat else None,
        worn=np.ones(n, bool) if worn else None,
    )


@pytest.fixture
def small_recording() -> Recording:
    t = np.arange(0, 2.0, 0.1)
    return Recording(
        name="walk1",
        devices={"phone": make_stream(), "earbuds": make_stream(50, 25.0, gyro=True, worn=True)},
        truth=Trajectory(t, np.stack([t, 0.5 * t], 1)),
        fixes=Fixes(t[::10], np.stack([t[::10], 0.5 * t[::10]], 1) + 1.0, np.full(2, 3.0)),
        labels=[(0.0, 1.0, "activity", "walk"), (1.0, 2.0, "activity", "stand")],
        meta={"subject": "u1", "mode": "STW", "placement": "HD", "source": "test"},
    )


def error_line(exc: WearnavError) -> str:
    """The error's message, asserting it is one line (as the CLI prints it)."""
    msg = str(exc)
    assert "\n" not in msg
    return msg


def run_cli(monkeypatch, capsys, *args) -> tuple[int, str, str]:
    """Run `wearnav ARGS` in-process: (exit code, stdout, stderr)."""
    import sys

    from wearnav import cli

    monkeypatch.setattr(sys, "argv", ["wearnav", *map(str, args)])
    code = 0
    try:
        cli.main()
    except SystemExit as e:
        code = e.code or 0
    out = capsys.readouterr()
    return code, out.out, out.err
