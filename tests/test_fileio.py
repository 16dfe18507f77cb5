"""fileio: atomic writes (old file or new, never torn), durability (fsync), the cleanup of
temporary files left by killed writers."""

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from wearnav.core import fileio
from wearnav.core.fileio import atomic_path, host_tag, savez_atomic, stale_temps, write_text_atomic

SRC = Path(__file__).resolve().parents[1] / "src"


def temps(path: Path) -> list[str]:
    return sorted(p.name for p in path.parent.glob(f".{path.name}.*.tmp"))


def dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def test_a_failed_write_keeps_the_old_file_and_leaves_no_temp(tmp_path):
    target = tmp_path / "r.json"
    write_text_atomic("old", target)
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:  # noqa: PT012  the raise inside atomic_path's block is the case under test
        tmp.write_text("half")
        raise RuntimeError("killed halfway")
    assert target.read_text() == "old"
    assert temps(target) == []
    write_text_atomic("new", target)
    assert target.read_text() == "new" and temps(target) == []
    assert (target.stat().st_mode & 0o777) != 0o600  # ordinary permissions, not mkstemp's


def test_temporary_names_carry_host_and_pid(tmp_path):
    with atomic_path(tmp_path / "a.b.json") as tmp:
        assert tmp.parent == tmp_path
        assert tmp.name.startswith(f".a.b.json.{host_tag()}.{os.getpid()}.") and tmp.name.endswith(".tmp")


def test_durable_fsyncs_the_file_before_the_rename_and_the_folder_after(tmp_path, monkeypatch):
    events = []
    real_fsync, real_replace = os.fsync, os.replace
    monkeypatch.setattr(
        fileio.os, "fsync", lambda fd: (events.append(("fsync", os.readlink(f"/proc/self/fd/{fd}"))), real_fsync(fd))[1]
    )
    monkeypatch.setattr(fileio.os, "replace", lambda a, b: (events.append(("replace", str(b))), real_replace(a, b))[1])
    target = tmp_path / "metrics.json"
    write_text_atomic("{}", target)
    assert [e[0] for e in events] == ["replace"]  # not durable: no fsync
    events.clear()
    write_text_atomic("{}", target, durable=True)
    assert [e[0] for e in events] == ["fsync", "replace", "fsync"]
    assert Path(events[0][1]).name.startswith(".metrics.json.") and events[0][1].endswith(".tmp")
    assert events[1][1] == str(target) and events[2][1] == str(tmp_path)


def test_stale_temps_of_dead_writers_on_this_host_are_removed_when_the_next_write_starts(tmp_path):
    target = tmp_path / "state.pt"
    dead, live = dead_pid(), os.getppid()
    stale = tmp_path / f".state.pt.{host_tag()}.{dead}.abcd1234.tmp"
    running = tmp_path / f".state.pt.{host_tag()}.{live}.efgh5678.tmp"  # a writer still at work
    elsewhere = tmp_path / f".state.pt.otherhost.{dead}.ijkl9012.tmp"  # cannot tell if alive there
    other_target = tmp_path / f".state.pt.old.{host_tag()}.{dead}.mnop3456.tmp"  # of "state.pt.old"
    for p in (stale, running, elsewhere, other_target):
        p.write_text("partial")
    assert stale_temps(target) == [stale]
    with atomic_path(target) as tmp:
        assert not stale.exists()  # already at the start
        tmp.write_text("x")
    assert running.exists() and elsewhere.exists() and other_target.exists()


def test_savez_atomic_keeps_the_name_and_round_trips(tmp_path):
    path = savez_atomic(tmp_path / "cache.segments", a=np.arange(3), b=np.eye(2))
    assert path == tmp_path / "cache.segments" and sorted(os.listdir(tmp_path)) == ["cache.segments"]
    with np.load(path) as z:
        assert z["a"].tolist() == [0, 1, 2] and z["b"].shape == (2, 2)


# One process imports wearnav once, then forks a writer per kill (a fresh interpreter per kill
# would spend a second on imports each): the writer rewrites the target in a loop until killed.
FORK_SERVER = """
import json, os, sys
sys.path.insert(0, {src!r})
from wearnav.core.fileio import write_text_atomic
target = sys.argv[1]
for _ in sys.stdin:
    pid = os.fork()
    if pid == 0:
        print(os.getpid(), flush=True)
        version = 0
        while True:
            version += 1
            write_text_atomic(json.dumps({{"version": version, "payload": str(version % 10) * 2_000_000}}), target)
    os.waitpid(pid, 0)
    print("reaped", flush=True)
"""


def test_a_writer_killed_at_random_moments_leaves_the_old_or_the_new_file(tmp_path):
    """SIGKILL a process that rewrites a 2 MB result in a loop, 20 times at random moments: the
    target always parses as one complete version, and at most the killed writer's own temporary
    file is left (the next writer removes it when it starts)."""
    target = tmp_path / "metrics.json"
    rng = random.Random(0)
    in_flight = 0
    server = subprocess.Popen(
        [sys.executable, "-c", FORK_SERVER.format(src=str(SRC)), str(target)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        for k in range(20):
            server.stdin.write("go\n")
            server.stdin.flush()
            writer = int(server.stdout.readline())
            if k % 2:  # a random moment (most fall between two writes: json.dumps takes the time)
                time.sleep(rng.uniform(0.0, 0.08))
            else:  # the moment the writer's temporary file is seen: mid-write, even on a busy machine
                deadline = time.monotonic() + 10
                while not any(f".{writer}." in t for t in temps(target)) and time.monotonic() < deadline:
                    pass
            os.kill(writer, signal.SIGKILL)
            assert server.stdout.readline().strip() == "reaped"
            left = temps(target)
            assert len(left) <= 1, left  # the earlier writers' temporaries were cleaned up
            in_flight += len(left)
            if target.exists():
                doc = json.loads(target.read_text())
                assert doc["payload"] == str(doc["version"] % 10) * 2_000_000
    finally:
        server.kill()
        server.wait()
    assert target.exists()
    assert in_flight > 0  # some kills did land in the middle of a write
    write_text_atomic("{}", target)
    assert temps(target) == []
