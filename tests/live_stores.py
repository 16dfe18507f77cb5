"""The live receiver's two stores for the tests that run on both (issue 61): SQLite (a file) and
PostgreSQL (a throwaway cluster on a unix socket in a tmp dir, started with the server binaries of
this machine; skipped, saying why, where there are none). Import the fixtures into a test module:
``from live_stores import postgres_cluster, store_where``."""

from __future__ import annotations

import glob
import os
import pwd
import shutil
import subprocess
import tempfile
import uuid
from pathlib import Path

import pytest

from wearnav.live.store import open_store

# where initdb / pg_ctl may be: PATH, this machine's /usr/local/bin, Debian's package
SEARCH = [os.environ.get("PATH", ""), "/usr/local/bin", *sorted(glob.glob("/usr/lib/postgresql/*/bin"), reverse=True)]


def server_bin() -> Path | None:
    """The folder holding initdb and pg_ctl, or None."""
    for d in os.pathsep.join(SEARCH).split(os.pathsep):
        if d and (Path(d) / "initdb").is_file() and (Path(d) / "pg_ctl").is_file():
            return Path(d)
    return None


def _user() -> str | None:
    """The user the server runs as: the postgres one where we are root (initdb refuses root), else us."""
    if os.geteuid() != 0:
        return None
    for name in ("postgres", "nobody"):
        try:
            pwd.getpwnam(name)
            return name
        except KeyError:
            continue
    return None


@pytest.fixture(scope="session")
def postgres_cluster():
    """``(url_of, restart)``: a fresh PostgreSQL cluster (fsync on: the durability rule is tested as it
    holds) listening only on a unix socket; ``url_of()`` makes a new database and gives its URL,
    ``restart()`` restarts the server (its clients' connections break)."""
    pytest.importorskip("psycopg", reason="the [postgres] extra (psycopg 3) is not installed")
    bindir = server_bin()
    if bindir is None:
        pytest.skip(
            "no PostgreSQL server binaries (initdb, pg_ctl) on PATH, /usr/local/bin or /usr/lib/postgresql/*/bin"
        )
    user = _user()
    if os.geteuid() == 0 and user is None:
        pytest.skip("running as root with no postgres or nobody user to run the server as")
    root = Path(tempfile.mkdtemp(prefix="wearnav-pg-"))
    data, sock = root / "data", root / "sock"
    sock.mkdir()
    if user is not None:
        pw = pwd.getpwnam(user)
        for p in (root, sock):
            os.chown(p, pw.pw_uid, pw.pw_gid)
    as_user = {"user": user} if user is not None else {}
    env = {**os.environ, "LC_ALL": "C", "LANG": "C"}
    run = subprocess.run(
        [str(bindir / "initdb"), "-D", str(data), "-U", "postgres", "--auth=trust", "-E", "UTF8", "--no-sync"],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
        **as_user,
    )
    if run.returncode != 0:
        shutil.rmtree(root, ignore_errors=True)
        pytest.skip(f"initdb failed: {run.stderr.strip()[:300]}")
    # 100 connections: the many-threads test checks each of its 60 pushes from a connection of its
    # own while the receiver's are open (50 made it fail with "too many clients" when they overlapped)
    opts = f"-k {sock} -c listen_addresses='' -c fsync=on -c synchronous_commit=on -c max_connections=100"
    start = subprocess.run(
        [
            str(bindir / "pg_ctl"),
            "-D",
            str(data),
            "-o",
            opts,
            "-l",
            str(root / "server.log"),
            "-w",
            "-t",
            "60",
            "start",
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=90,
        **as_user,
    )
    if start.returncode != 0:
        log = (root / "server.log").read_text() if (root / "server.log").exists() else ""
        shutil.rmtree(root, ignore_errors=True)
        pytest.fail(f"pg_ctl start failed: {start.stderr.strip()} {log[-500:]}")
    import psycopg

    admin = f"postgresql://postgres@/postgres?host={sock}"

    def url_of() -> str:
        name = f"t_{uuid.uuid4().hex[:12]}"
        with psycopg.connect(admin, autocommit=True) as c:
            c.execute(f"CREATE DATABASE {name}")
        return f"postgresql://postgres@/{name}?host={sock}"

    def restart() -> None:
        run = subprocess.run(
            [str(bindir / "pg_ctl"), "-D", str(data), "-o", opts, "-l", str(root / "server.log"), "-m", "fast"]
            + ["-w", "-t", "60", "restart"],
            capture_output=True,
            text=True,
            env=env,
            timeout=90,
            **as_user,
        )
        assert run.returncode == 0, run.stderr

    try:
        yield url_of, restart
    finally:
        subprocess.run(
            [str(bindir / "pg_ctl"), "-D", str(data), "-m", "immediate", "-w", "stop"],
            capture_output=True,
            env=env,
            timeout=60,
            **as_user,
        )
        shutil.rmtree(root, ignore_errors=True)


@pytest.fixture(params=["sqlite", "postgresql"])
def store_where(request, tmp_path) -> str:
    """Where a test's store is: a SQLite file in its tmp dir, or a new database on the cluster."""
    if request.param == "sqlite":
        return str(tmp_path / "live.db")
    url_of, _ = request.getfixturevalue("postgres_cluster")
    return url_of()


def count(where: str) -> int:
    store = open_store(where)
    try:
        return store.count()
    finally:
        store.close()


def message_ids(where: str, session: str) -> set[int]:
    store = open_store(where)
    try:
        return {m for _d, m in store.message_ids(session)}
    finally:
        store.close()


__all__ = ["count", "message_ids", "postgres_cluster", "server_bin", "store_where"]
