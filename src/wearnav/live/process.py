"""A real ``wearnav live`` process on 127.0.0.1 and a free port: for ``wearnav live bench`` and the
receiver's tests (real uvicorn, real HTTP, SIGKILL when asked)."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

SRC = Path(__file__).resolve().parents[2]  # the folder holding the wearnav package


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def env() -> dict[str, str]:
    """The environment a ``wearnav`` child process runs in: this package first on its path, one
    torch thread."""
    path = os.pathsep.join(p for p in (str(SRC), os.environ.get("PYTHONPATH", "")) if p)
    return {**os.environ, "PYTHONPATH": path, "OMP_NUM_THREADS": "1"}


def cpu_s(pid: int) -> float | None:
    """CPU seconds (user + system) process ``pid`` has used so far (Linux /proc), or None."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, AttributeError, IndexError):
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def children(pid: int) -> list[int]:
    """The processes whose parent is ``pid`` (Linux /proc; none elsewhere)."""
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            if int(stat.read_text().rsplit(")", 1)[1].split()[1]) == pid:
                out.append(int(stat.parent.name))
        except (OSError, ValueError, IndexError):
            continue
    return out


def start_tracker(
    store: Path | str, shard: tuple[int, int], *args: str, stats: Path | None = None, log: Path | None = None
) -> subprocess.Popen:
    """``wearnav live track --store STORE --shard i/n ARGS [--stats STATS]`` beside a receiver on
    ``store`` (``wearnav live --trackers``, the bench, the tests); its output to ``log`` (appended),
    or this process's."""
    cmd = [sys.executable, "-m", "wearnav", "live", "track", "--store", str(store), "--shard", f"{shard[0]}/{shard[1]}"]
    cmd += [*args, *(["--stats", str(stats)] if stats is not None else [])]
    if log is None:
        return subprocess.Popen(cmd, env=env())
    with open(log, "ab") as out:
        return subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, env=env())


class LiveServer:
    """``wearnav live --host 127.0.0.1 --port P --store DB ARGS``; stdout and stderr to ``log``."""

    def __init__(
        self,
        store: Path,
        *args: str,
        port: int | None = None,
        token: str | None = None,
        store_url: str | None = None,
    ):
        """``store``: the SQLite file (and where the log goes beside it); ``store_url``: what
        ``--store`` says instead (a ``postgresql://`` URL)."""
        self.store, self.args, self.token = Path(store), list(args), token
        self.store_url = store_url or str(self.store)
        self.port = port or free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.log = self.store.with_suffix(f".{self.port}.log")
        self.proc: subprocess.Popen | None = None

    def start(self, timeout_s: float = 30.0) -> LiveServer:
        import httpx  # (the bench's and the tests' client; `wearnav live --trackers` uses start_tracker only)

        cmd = [
            sys.executable,
            "-m",
            "wearnav",
            "live",
            "--host",
            "127.0.0.1",
            "--port",
            str(self.port),
            "--store",
            self.store_url,
            *self.args,
        ]
        with open(self.log, "ab") as log:
            self.proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env())
        headers = {"authorization": f"Bearer {self.token}"} if self.token else {}
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"wearnav live exited {self.proc.returncode}: {self.log.read_text()}")
            try:
                if httpx.get(f"{self.url}/sessions", headers=headers, timeout=1.0).status_code in (200, 401):
                    return self
            except httpx.TransportError:
                pass
            time.sleep(0.1)
        self.stop()
        raise RuntimeError(f"wearnav live did not answer in {timeout_s} s: {self.log.read_text()}")

    def kill(self) -> None:
        """SIGKILL: no clean-up of any kind."""
        if self.proc is not None and self.proc.poll() is None:
            os.kill(self.proc.pid, signal.SIGKILL)
            self.proc.wait(10)

    def stop(self, signum: int = signal.SIGTERM) -> int | None:
        """Stop the server with ``signum`` (SIGTERM; SIGINT as Ctrl-C), SIGKILL after 10 s; its exit code."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signum)
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.kill()
        return None if self.proc is None else self.proc.returncode

    def cpu_s(self) -> float | None:
        """CPU seconds (user + system) the server process, and the receivers it started
        (``--workers``), have used so far (Linux /proc), or None."""
        if self.proc is None:
            return None
        own = cpu_s(self.proc.pid)
        if own is None:
            return None
        return own + sum(c for pid in children(self.proc.pid) if (c := cpu_s(pid)) is not None)

    def stored(self) -> int:
        """How many messages the store holds."""
        from wearnav.live.store import open_store

        store = open_store(self.store_url)
        try:
            return store.count()
        finally:
            store.close()

    def output(self) -> str:
        return self.log.read_text(errors="replace")

    def __enter__(self) -> LiveServer:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()


__all__ = ["LiveServer", "children", "cpu_s", "env", "free_port", "start_tracker"]
