"""Bad input never loses a file, never passes silently, never shows a traceback (issue 6).

The property tests drive ``wearnav`` in-process (``cli.main`` with ``sys.argv`` patched) on small
slices of every format, malformed by hypothesis (truncations, renamed columns, corrupt values,
duplicated / reversed rows, missing or empty files), and on bad ``--out`` paths. Every outcome must
be either a valid dataset (it opens and every recording loads) or exactly one ``error:`` line on
stderr with exit 2 and no output folder; never a traceback, a leftover ``*.partial`` folder or a
changed file outside ``--out``. Outcome counts are printed at the end of the run
(``WEARNAV_ROBUSTNESS_COUNTS=path.json`` also writes them). ``WEARNAV_ROBUSTNESS_EXAMPLES`` sets the
examples per property (default 30).
"""

from __future__ import annotations

import collections
import contextlib
import hashlib
import io
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path
from unittest import mock

import h5py
import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import SHARED_DATA, make_stream
from robustness_inputs import BAD_VALUES, FORMATS, KINDS, Mutation, apply, build_seed, materialise, source_arg
from wearnav import cli
from wearnav.dataset import Dataset, DatasetWriter, write_dataset
from wearnav.errors import Terminated, ValidationError, WearnavWarning
from wearnav.live import replay
from wearnav.live.app import Receiver
from wearnav.live.push import BadPush
from wearnav.live.store import Store
from wearnav.recording import Recording

EXAMPLES = int(os.environ.get("WEARNAV_ROBUSTNESS_EXAMPLES", "30"))
PROPERTY = settings(
    max_examples=EXAMPLES,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
OUTCOMES: collections.Counter = collections.Counter()  # (class of input, outcome) -> count


@pytest.fixture(scope="module", autouse=True)
def report_outcomes(request):
    yield
    if not OUTCOMES:
        return
    table = collections.defaultdict(dict)
    for (cls, outcome), n in sorted(OUTCOMES.items()):
        table[cls][outcome] = n
    total = collections.Counter()
    for (_, outcome), n in OUTCOMES.items():
        total[outcome] += n
    lines = [
        f"malformed inputs tried: {sum(total.values())} -> " + ", ".join(f"{k} {v}" for k, v in sorted(total.items()))
    ]
    lines += [f"  {cls}: " + ", ".join(f"{k} {v}" for k, v in sorted(o.items())) for cls, o in table.items()]
    reporter = request.config.pluginmanager.get_plugin("terminalreporter")
    capture = request.config.pluginmanager.get_plugin("capturemanager")
    if reporter is not None:
        with capture.global_and_fixture_disabled() if capture else contextlib.nullcontext():
            reporter.write_line("")
            for ln in lines:
                reporter.write_line(ln)
    if os.environ.get("WEARNAV_ROBUSTNESS_COUNTS"):
        Path(os.environ["WEARNAV_ROBUSTNESS_COUNTS"]).write_text(
            json.dumps({"total": dict(total), "by_class": table}, indent=2)
        )


# ---- helpers -------------------------------------------------------------------------------------


def run_cli(*args, cwd: Path | None = None) -> tuple[int, str, str]:
    """``wearnav ARGS`` in-process: (exit code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    code = 0
    with contextlib.ExitStack() as stack:
        stack.enter_context(mock.patch.object(sys, "argv", ["wearnav", *map(str, args)]))
        stack.enter_context(contextlib.redirect_stdout(out))
        stack.enter_context(contextlib.redirect_stderr(err))
        if cwd is not None:
            stack.enter_context(contextlib.chdir(cwd))
        try:
            cli.main()
        except SystemExit as e:
            code = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
    return code, out.getvalue(), err.getvalue()


def snapshot(root: Path, exclude: Path | None = None) -> dict[str, tuple]:
    """Every path under ``root`` (outside ``exclude``) with its type, size and content hash."""
    snap = {}
    for dirpath, dirnames, filenames in os.walk(root):
        d = Path(dirpath)
        if exclude is not None and (d == exclude or exclude in d.parents):
            dirnames[:] = []
            continue
        for name in dirnames + filenames:
            p = d / name
            if exclude is not None and p == exclude:
                continue
            if p.is_file() and not p.is_symlink():
                snap[str(p.relative_to(root))] = ("file", hashlib.sha1(p.read_bytes()).hexdigest())
            else:
                snap[str(p.relative_to(root))] = ("dir" if p.is_dir() else "other",)
    return snap


def outcome(code: int, stdout: str, stderr: str, out: Path, out_existed: bool) -> str:
    """ "valid", "error" or "other" (anything the promise does not allow)."""
    if [p.name for p in out.parent.iterdir() if p.name.startswith(f".{out.name}.")]:
        return "other"  # a work folder was left behind
    lines = stderr.splitlines()
    if code == 0:
        if not all(ln.startswith("warning: ") for ln in lines):
            return "other"
        ds = Dataset.open(out)
        for name in ds.names:
            ds.load(name)
        return "valid"
    if code == 2 and len(lines) == 1 and lines[0].startswith("error: ") and not stdout:
        return "error" if (out.exists() == out_existed) else "other"
    return "other"


def error_of(stderr: str, cls: str | None = None) -> str:
    """The one ``error:`` line of ``stderr`` (asserted), counted under ``cls``."""
    lines = stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), stderr
    if cls:
        OUTCOMES[(cls, "error")] += 1
    return lines[0]


_SEEDS: dict[str, dict[str, str]] = {}


def seed(fmt: str) -> dict[str, str]:
    if fmt != "sensorlogger" and not SHARED_DATA.is_dir():
        pytest.skip(f"real data not found at {SHARED_DATA}")
    if fmt not in _SEEDS:
        _SEEDS[fmt] = build_seed(fmt, SHARED_DATA)
    return _SEEDS[fmt]


mutations = st.builds(
    Mutation,
    kind=st.sampled_from(KINDS),
    side=st.floats(0, 1, exclude_max=True),
    where=st.floats(0, 1, exclude_max=True),
    column=st.floats(0, 1, exclude_max=True),
    value=st.sampled_from(BAD_VALUES),
)


# ---- every importer, malformed ------------------------------------------------------------------


@pytest.mark.parametrize("fmt", FORMATS)
def test_seed_imports_cleanly(fmt, tmp_path):
    """The unmutated slices are valid: the property below would be empty without this."""
    materialise(seed(fmt), tmp_path / "src")
    code, out, err = run_cli("import", fmt, source_arg(fmt, tmp_path / "src"), "--out", tmp_path / "out")
    assert code == 0 and err == "", err
    ds = Dataset.open(tmp_path / "out")
    assert len(ds) == 1 and len(ds.load(ds.names[0]).devices["phone"]) > 100


@pytest.mark.parametrize("fmt", FORMATS)
def test_malformed_input_is_a_dataset_or_one_line(fmt):
    data = seed(fmt)

    @PROPERTY
    @given(m=mutations)
    def check(m):
        with tempfile.TemporaryDirectory() as tmp:
            tmp = Path(tmp)
            materialise(data, tmp / "src")
            apply(m, fmt, tmp / "src")
            before = snapshot(tmp)
            code, out, err = run_cli("import", fmt, source_arg(fmt, tmp / "src"), "--out", tmp / "out")
            result = outcome(code, out, err, tmp / "out", out_existed=False)
            OUTCOMES[(f"import {fmt}", result)] += 1
            assert result != "other", f"{m.describe()}: exit {code}, stderr {err!r}"
            assert snapshot(tmp, exclude=tmp / "out") == before, "a file outside --out changed"

    check()


def _corrupt_acc(fmt: str, root: Path, value: str) -> None:
    """Write ``value`` into one accelerometer column of every 20th sample (5 %)."""
    from robustness_inputs import TARGETS

    rel, sep = TARGETS[fmt]
    path = root / rel
    lines = path.read_text().splitlines()
    acc_field = {
        "ilc2": ("TYPE_ACCELEROMETER", 2),
        "ipin2023": ("ACCE", 3),
        "motionsense": (None, 10),
        "uci-hapt": (None, 0),
        "uji-phone-watch": (None, 0),
        "oxford-steps": (None, 1),
        "sensorlogger": (None, 2),
    }[fmt]
    tag, j = acc_field
    rows = [
        i
        for i, ln in enumerate(lines)
        if ln and ln[0] not in "#%" and (tag is None or ln.split(sep)[0 if fmt == "ipin2023" else 1] == tag)
    ]
    if rel.endswith(".csv"):
        rows = rows[1:]
    for i in rows[::20]:
        fields = lines[i].split(sep) if sep else lines[i].split()
        fields[j] = value
        lines[i] = (sep or " ").join(fields)
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("fmt", FORMATS)
def test_five_percent_absurd_acc_is_refused(fmt, tmp_path):
    materialise(seed(fmt), tmp_path / "src")
    _corrupt_acc(fmt, tmp_path / "src", "1e30")
    code, _, err = run_cli("import", fmt, source_arg(fmt, tmp_path / "src"), "--out", tmp_path / "out")
    assert code == 2 and not (tmp_path / "out").exists()
    line = error_of(err, "5 % of acc samples 1e30")
    assert "16 g" in line or "acc" in line.lower(), line


# ---- the live receiver: the same malformations in a push (issue 23 §3) ----------------------------

_PUSH_SEED: list = []
_NUMBER_LITERAL = re.compile(rb"(?<=[:,\[] )-?\d[\d.eE+-]*")
PUSH_VALUES = [*BAD_VALUES, "-1", "1e300", '"x"', "null", "true", "[]", "{}"]


def _push_seed() -> tuple[list[bytes], str, bool]:
    """The Sensor Logger seed export as the app would push it (1-s batches), as JSON bodies."""
    if not _PUSH_SEED:
        with tempfile.TemporaryDirectory() as tmp:
            materialise(seed("sensorlogger"), Path(tmp) / "src")
            rp = replay.build(Path(tmp) / "src" / "export", batch_s=1.0, session_id="seed")
        bodies = [json.dumps({k: v for k, v in m.items() if not k.startswith("_")}).encode() for m in rp.messages]
        _PUSH_SEED.append((bodies, rp.platform, rp.standardised))
    return _PUSH_SEED[0]


@PROPERTY
@given(
    kind=st.sampled_from(["corrupt_value", "truncate", "duplicate", "reverse", "drop"]),
    msg=st.floats(0, 1, exclude_max=True),
    where=st.floats(0, 1, exclude_max=True),
    value=st.sampled_from(PUSH_VALUES),
)
def test_malformed_push_is_stored_or_refused_and_never_poisons_the_session(kind, msg, where, value):
    """A push with a corrupt value (the importer cases' values and JSON's other types), cut short,
    repeated, out of order or missing: accepted, or refused with a 4xx and nothing stored; the
    store holds exactly the accepted messages, and the session still becomes a Recording."""
    bodies, platform, standardised = _push_seed()
    bodies = list(bodies)
    i = int(msg * len(bodies))
    if kind == "corrupt_value":
        spots = list(_NUMBER_LITERAL.finditer(bodies[i]))
        m = spots[int(where * len(spots))]
        bodies[i] = bodies[i][: m.start()] + value.encode() + bodies[i][m.end() :]
    elif kind == "truncate":
        bodies[i] = bodies[i][: int(where * len(bodies[i]))]
    elif kind == "duplicate":
        bodies.insert(i, bodies[i])
    elif kind == "reverse":
        bodies.reverse()
    else:
        del bodies[i]
    with tempfile.TemporaryDirectory() as tmp:
        rx = Receiver(
            Store(Path(tmp) / "live.db"), None, 1 << 22, 1e6, None, platform, standardised, 120.0, 7 * 86400.0
        )
        new = 0
        for j, b in enumerate(bodies):
            try:
                sid = rx.accept(b, platform, standardised)
                result = "stored" if sid else "repeat"
                new += sid is not None
            except BadPush as exc:
                assert 400 <= exc.status < 500, exc.message  # noqa: PT017  either outcome is valid; the refusal is what the except checks
                result = f"refused {exc.status}"
            if j == i or kind in ("reverse", "drop"):  # the message changed, or every one of the sequence
                OUTCOMES[(f"push {kind}", result)] += 1
        assert rx.store.count() == new
        rec = rx.buffers["seed"].recording()
        assert set(rec.devices) == {"phone", "watch", "earbuds"}
        rx.store.close()


# ---- damaged dataset folders and recording files -----------------------------------------------


def _small_dataset_files() -> dict[str, str]:
    with tempfile.TemporaryDirectory() as tmp:
        root = _dataset(Path(tmp) / "d", names=("a", "001"))
        return {f"d/{p.name}": p.read_bytes().decode("latin-1") for p in root.iterdir()}


def _materialise_bytes(files: dict[str, str], root: Path) -> None:
    for rel, text in files.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_bytes(text.encode("latin-1"))


def _info_outcome(code: int, out: str, err: str) -> str:
    lines = err.splitlines()
    if code == 0 and not lines:
        json.loads(out)
        return "valid"
    if code == 2 and len(lines) == 1 and lines[0].startswith("error: ") and not out:
        return "error"
    return "other"


def test_malformed_manifest_is_a_dataset_or_one_line():
    files = _small_dataset_files()

    @PROPERTY
    @given(m=mutations)
    def check(m):
        with tempfile.TemporaryDirectory() as tmp:
            tmp = Path(tmp)
            _materialise_bytes(files, tmp)
            apply(m, "dataset", tmp)
            code, out, err = run_cli("info", tmp / "d")
            result = _info_outcome(code, out, err)
            OUTCOMES[("info on a damaged dataset folder", result)] += 1
            assert result != "other", f"{m.describe()}: exit {code}, stderr {err!r}"

    check()


def _h5_paths(path: Path) -> list[str]:
    names: list[str] = []
    with h5py.File(path, "r") as f:
        f.visit(names.append)
    return sorted(names)


H5_EDITS = ["delete", "as_text", "as_scalar", "as_2d", "attr_meta", "attr_name", "attr_format", "truncate", "flip_byte"]


@PROPERTY
@given(
    edit=st.sampled_from(H5_EDITS),
    which=st.floats(0, 1, exclude_max=True),
    value=st.sampled_from([b"\xff\xfe", "{}", "[]", "null", 3, np.arange(3), "not json", ""]),
)
def test_damaged_recording_file_is_loaded_or_one_line(edit, which, value):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "r.h5"
        rec = Recording(
            "r",
            {"phone": make_stream(n=30), "watch": make_stream(n=20, gyro=False)},
            labels=[(0.0, 0.1, "activity", "walk")],
            meta={"subject": "u1"},
        )
        rec.save(path)
        objects = _h5_paths(path)
        target = objects[int(which * len(objects))]
        if edit in ("truncate", "flip_byte"):
            raw = bytearray(path.read_bytes())
            k = int(which * len(raw))
            if edit == "truncate":
                raw = raw[:k]
            else:
                raw[k] ^= 0xFF
            path.write_bytes(bytes(raw))
        else:
            with h5py.File(path, "r+") as f:
                if edit == "delete":
                    del f[target]
                elif edit in ("as_text", "as_scalar", "as_2d"):
                    del f[target]
                    f[target] = {
                        "as_text": np.array(["x", "y"], dtype=object).astype("S"),
                        "as_scalar": np.float64(1.0),
                        "as_2d": np.ones((2, 2)),
                    }[edit]
                else:
                    f.attrs[edit[len("attr_") :]] = value
        code, out, err = run_cli("info", path)
        result = _info_outcome(code, out, err)
        OUTCOMES[("info on a damaged recording file", result)] += 1
        assert result != "other", f"{edit} {target} {value!r}: exit {code}, stderr {err!r}"


# ---- Recording / Dataset round trip ---------------------------------------------------------------

NAMES = st.one_of(
    st.sampled_from(
        [
            "001",
            "0",
            "null",
            "NaN",
            "None",
            "True",
            "1e3",
            "",
            ".",
            "..",
            "a/b",
            "a\x00b",
            " x",
            "x ",
            "a,b",
            'a"b',
            "a\nb",
            "a\rb",
            "é#;",
            "\ud800",
            "x" * 250,
        ]
    ),
    st.text(max_size=12),
)


@PROPERTY
@given(name=NAMES, device=NAMES, label=st.text(max_size=8), split=NAMES)
def test_names_round_trip_or_are_refused(name, device, label, split):
    try:
        rec = Recording(name, {device: make_stream(n=20)}, labels=[(0.0, 0.1, "activity", label)])
    except ValidationError as exc:
        assert "\n" not in str(exc)  # noqa: PT017  either outcome is valid; the refusal is what the except checks
        OUTCOMES[("recording names", "error")] += 1
        return
    with tempfile.TemporaryDirectory() as tmp:
        try:
            ds = write_dataset(Path(tmp) / "d", [(rec, split)])
        except ValidationError as exc:  # a label or split that cannot be stored
            assert "\n" not in str(exc) and not (Path(tmp) / "d").exists()  # noqa: PT017  either outcome is valid; the refusal is what the except checks
            OUTCOMES[("recording names", "error")] += 1
            return
        assert ds.names == [name]
        back = ds.load(name)
        assert back.name == name and list(back.devices) == [device]
        assert back.labels["value"].tolist() == [label]
        assert ds.manifest["split"].tolist() == [split]
    OUTCOMES[("recording names", "valid")] += 1


def _valid_recording():
    return Recording("r", {"phone": make_stream(n=50)}, labels=[(0.0, 0.2, "activity", "walk")])


CHANGES = {
    "nan acc": lambda r: r.devices["phone"].acc.__setitem__((3, 0), np.nan),
    "reversed time": lambda r: setattr(r.devices["phone"], "t", r.devices["phone"].t[::-1].copy()),
    "absurd acc": lambda r: r.devices["phone"].acc.__setitem__((3, 0), 1e30),
    "absurd gyro": lambda r: r.devices["phone"].gyro.__setitem__((3, 0), 1e4),
    "device name with /": lambda r: r.devices.update({"a/b": r.devices.pop("phone")}),
    "device name with NUL": lambda r: r.devices.update({"a\x00b": r.devices.pop("phone")}),
    "empty device name": lambda r: r.devices.update({"": r.devices.pop("phone")}),
    "recording name with /": lambda r: setattr(r, "name", "x/y"),
    "no devices": lambda r: r.devices.clear(),
    "overlapping labels": lambda r: setattr(
        r,
        "labels",
        pd.DataFrame(
            [(0.0, 1.0, "activity", "a"), (0.5, 1.5, "activity", "b")], columns=["start", "end", "kind", "value"]
        ),
    ),
    "meta not json": lambda r: r.meta.update({"x": object()}),
}


@pytest.mark.parametrize("change", list(CHANGES))
def test_save_refuses_what_construction_would(change, tmp_path):
    rec = _valid_recording()
    CHANGES[change](rec)
    with pytest.raises(ValidationError) as info:
        rec.save(tmp_path / "r.h5")
    assert "\n" not in str(info.value)
    assert list(tmp_path.iterdir()) == []
    OUTCOMES[("changed after construction", "error")] += 1


# ---- --out: never lose data ----------------------------------------------------------------------


def _dataset(path: Path, names=("a",)) -> Path:
    write_dataset(path, [(Recording(n, {"phone": make_stream(n=20)}), "") for n in names])
    return path


def _prepare_out(case: str, tmp: Path) -> Path:
    if case == "existing file":
        (tmp / "out").write_text("mine")
    elif case == "under a file":
        (tmp / "f").write_text("mine")
        return tmp / "f" / "out"
    elif case == "folder with a manifest.csv":
        (tmp / "out").mkdir()
        (tmp / "out" / "manifest.csv").write_text("name,file\n")
        (tmp / "out" / "notes.txt").write_text("precious")
    elif case == "dataset plus a user file":
        _dataset(tmp / "out")
        (tmp / "out" / "notes.txt").write_text("precious")
    elif case == "dataset with a sub-folder":
        _dataset(tmp / "out")
        (tmp / "out" / "figures").mkdir()
    elif case == "the working folder":
        return Path(".")
    elif case == "the folder above":
        return Path("..")
    elif case == "named pipe":
        os.mkfifo(tmp / "out")
    elif case == "unwritable place":
        return Path("/proc/wearnav-test-out")
    elif case == "name too long":
        return tmp / ("x" * 300)
    elif case == "empty folder":
        (tmp / "out").mkdir()
    elif case == "earlier wearnav dataset":
        _dataset(tmp / "out", names=("old1", "old2"))
    return tmp / "out"


OUT_CASES = [
    "existing file",
    "under a file",
    "folder with a manifest.csv",
    "dataset plus a user file",
    "dataset with a sub-folder",
    "the working folder",
    "the folder above",
    "named pipe",
    "unwritable place",
    "name too long",
    "empty folder",
    "earlier wearnav dataset",
]


@pytest.mark.parametrize("case", OUT_CASES)
def test_bad_out_paths(case, tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    materialise(seed("sensorlogger"), work / "src")
    out = _prepare_out(case, work)
    resolved = out if out.is_absolute() else (work / out)

    def exists(p: Path) -> bool:
        try:
            return p.exists()
        except OSError:  # e.g. the name is too long to look up
            return False

    existed = exists(resolved)
    before = snapshot(tmp_path)
    code, stdout, err = run_cli("import", "sensorlogger", work / "src" / "export", "--out", out, cwd=work)
    if case == "earlier wearnav dataset":  # replaced only when asked (issue 22)
        assert code == 2 and "already holds a wearnav dataset" in error_of(err) and "--overwrite" in err
        assert snapshot(tmp_path) == before
        code, stdout, err = run_cli(
            "import", "sensorlogger", work / "src" / "export", "--out", out, "--overwrite", cwd=work
        )
    if case in ("empty folder", "earlier wearnav dataset"):
        assert code == 0, err
        assert Dataset.open(resolved).names == ["export"]
        OUTCOMES[("bad --out", "valid")] += 1
        return
    assert code == 2, (code, err)
    error_of(err)
    if not str(resolved).startswith("/proc"):
        assert snapshot(tmp_path) == before, "a file changed although the import was refused"
    assert existed == exists(resolved)
    OUTCOMES[("bad --out", "error")] += 1


def test_replacing_keeps_nothing_of_the_old_dataset_and_no_work_folders(tmp_path):
    _dataset(tmp_path / "d", names=("a", "b"))
    _dataset(tmp_path / "d", names=("c",))
    assert Dataset.open(tmp_path / "d").names == ["c"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d"]


def test_simulate_refuses_a_foreign_folder(tmp_path):
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "manifest.csv").write_text("x")
    (tmp_path / "mine" / "precious.txt").write_text("p")
    code, _, err = run_cli("simulate", "--preset", "tiny", "--out", tmp_path / "mine")
    assert code == 2 and "not a wearnav dataset" in error_of(err)
    assert (tmp_path / "mine" / "precious.txt").read_text() == "p"


# ---- SIGTERM and stale work folders -------------------------------------------------------------


def test_sigterm_inside_the_writer_removes_the_partial_folder(tmp_path):
    before = signal.getsignal(signal.SIGTERM)  # the default, or SIG_IGN under a runner that ignores it
    with pytest.raises(Terminated):  # noqa: PT012  the raise inside the writer's block is the case under test
        with DatasetWriter(tmp_path / "d") as w:
            w.add(Recording("a", {"phone": make_stream(n=20)}))
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(1)  # the handler raises as soon as Python runs again
    assert list(tmp_path.iterdir()) == []
    assert signal.getsignal(signal.SIGTERM) is before  # the writer gave its handler back


def test_sigterm_during_simulate_leaves_nothing(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(Path(cli.__file__).parents[1])}
    proc = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "from wearnav.cli import main; main()",
            "simulate",
            "--preset",
            "tiny",
            "--out",
            str(tmp_path / "sim"),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    deadline = time.time() + 60
    while time.time() < deadline and not list(tmp_path.glob(".sim.*.partial/*.h5")):
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    assert (
        error_of(err)
        == f"error: terminated (SIGTERM); nothing was written to {tmp_path / 'sim'}; run the same command again"
    )
    assert list(tmp_path.iterdir()) == []


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def test_stale_work_folders_of_dead_writers_are_cleaned(tmp_path):
    import socket

    host = socket.gethostname().replace(".", "_")
    dead = _dead_pid()
    stale = tmp_path / f".d.{host}.{dead}.abc123.partial"
    stale.mkdir()
    (stale / "x.h5").write_text("half")
    live = tmp_path / f".d.{host}.{os.getpid()}.zzz.partial"  # this process: still writing
    live.mkdir()
    _dataset(tmp_path / "d")
    assert not stale.exists() and live.exists()


def test_a_replacement_cut_between_its_renames_is_rolled_back(tmp_path):
    import socket

    _dataset(tmp_path / "keep", names=("x",))
    host = socket.gethostname().replace(".", "_")
    old = tmp_path / f".d.{host}.{_dead_pid()}.q1.old"
    os.replace(tmp_path / "keep", old)  # as if killed after moving "d" aside, before the new one landed
    _dataset(tmp_path / "other")  # a writer of another root leaves it alone
    assert old.exists()
    writer = DatasetWriter(tmp_path / "d")  # a writer of "d" moves it back first
    writer.abort()
    assert not old.exists() and Dataset.open(tmp_path / "d").names == ["x"]


# ---- Dataset.open checks the folder -------------------------------------------------------------


@pytest.mark.parametrize(
    "edit, needle",
    [
        (lambda m: m.assign(duration="ten"), "duration"),
        (lambda m: pd.concat([m, m]), "more than once"),
        (lambda m: m.assign(file="missing.h5"), "not in the folder"),
        (lambda m: m.assign(file="../x.h5"), "file name"),
        (lambda m: m.assign(truth_points="-1"), "truth_points"),
    ],
)
def test_manifest_is_checked(edit, needle, tmp_path):
    root = _dataset(tmp_path / "d")
    m = pd.read_csv(root / "manifest.csv", dtype=str, keep_default_na=False)
    edit(m).to_csv(root / "manifest.csv", index=False)
    code, _, err = run_cli("info", root)
    assert code == 2 and needle in error_of(err, "bad manifest")


def test_unlisted_recording_and_newer_format_are_refused(tmp_path):
    root = _dataset(tmp_path / "d")
    (root / "dataset.yaml").write_text("format: wearnav.dataset\nformat_version: 99\n")
    code, _, err = run_cli("info", root)
    assert code == 2 and "newer wearnav" in error_of(err, "bad manifest")
    root = _dataset(tmp_path / "e")
    Recording("stray", {"phone": make_stream(n=20)}).save(root / "stray.h5")
    code, _, err = run_cli("info", root)
    assert code == 2 and "not listed" in error_of(err, "bad manifest")


def test_names_like_numbers_survive_the_manifest(tmp_path):
    root = _dataset(tmp_path / "d", names=("001", "0", "null", "NaN"))
    ds = Dataset.open(root)
    assert ds.names == ["001", "0", "null", "NaN"]
    assert [r.name for r in ds] == ds.names


# ---- one line, always ---------------------------------------------------------------------------


def _h5_variant(tmp_path, edit) -> Path:
    path = tmp_path / "r.h5"
    Recording("r", {"phone": make_stream(n=20)}).save(path)
    with h5py.File(path, "r+") as f:
        edit(f)
    return path


def _devices_dataset(f):
    del f["devices"]
    f["devices"] = np.zeros(3)


@pytest.mark.parametrize(
    "edit, needle",
    [
        (lambda f: f.attrs.__setitem__("meta", "{not json"), "corrupt recording"),
        (lambda f: f.attrs.__setitem__("meta", "[1, 2]"), "meta"),
        (_devices_dataset, "not a group"),
        (lambda f: f.attrs.__setitem__("version", 7), "newer wearnav"),
        (lambda f: f["devices/phone/acc"].__setitem__((0, 0), np.nan), "non-finite"),
    ],
)
def test_bad_h5_is_one_line(edit, needle, tmp_path):
    code, _, err = run_cli("info", _h5_variant(tmp_path, edit))
    assert code == 2 and needle in error_of(err, "bad recording file") and "r.h5" in err


def test_cli_options_and_empty_datasets_are_one_line(tmp_path):
    code, _, err = run_cli("simulate", "--preset", "tiny", "--seed", "-1", "--out", tmp_path / "s")
    assert code == 2 and "--seed" in error_of(err, "bad options / empty dataset")
    code, _, err = run_cli("import", "oxford-steps", tmp_path, "--out", tmp_path / "o", "--limit", "-3")
    assert code == 2 and "--limit" in error_of(err, "bad options / empty dataset")
    code, _, err = run_cli("import", "oxford-steps", tmp_path)
    assert code == 2 and "--out" in error_of(err, "bad options / empty dataset")
    empty = tmp_path / "empty"
    write_dataset(empty, [])
    code, _, err = run_cli("plot", empty, "--out", tmp_path / "p.png")
    assert code == 2 and "no recordings" in error_of(err, "bad options / empty dataset")


def test_named_pipes_are_refused_not_read(tmp_path):
    os.mkfifo(tmp_path / "fifo.h5")
    code, _, err = run_cli("info", tmp_path / "fifo.h5")
    assert code == 2 and "not a regular file" in error_of(err, "named pipes")
    (tmp_path / "RawData").mkdir()
    os.mkfifo(tmp_path / "RawData" / "acc_exp01_user01.txt")
    (tmp_path / "RawData" / "gyro_exp01_user01.txt").write_text("0 0 0\n0 0 0\n")
    (tmp_path / "RawData" / "labels.txt").write_text("1 1 1 1 2\n")
    (tmp_path / "activity_labels.txt").write_text("1 WALKING\n")
    code, _, err = run_cli("import", "uci-hapt", tmp_path, "--out", tmp_path / "o")
    assert code == 2 and "not a regular file" in error_of(err, "named pipes")
    os.mkfifo(tmp_path / "trace.txt")
    code, _, err = run_cli("import", "ilc2", tmp_path / "trace.txt", "--out", tmp_path / "o")
    assert code == 2 and "not a regular file" in error_of(err, "named pipes")


def test_multiline_library_messages_become_one_line(tmp_path):
    from wearnav.errors import FormatError

    assert str(FormatError("line one\nline two\r\n  three", "f.csv")) == "f.csv: line one line two three"


def test_unexpected_exceptions_are_one_line_and_say_bug(tmp_path, monkeypatch):
    import wearnav.dataset

    def broken(*a, **k):
        raise RuntimeError("boom\nsecond line")

    monkeypatch.setattr(wearnav.dataset.Dataset, "open", classmethod(broken))
    (tmp_path / "d").mkdir()
    code, _, err = run_cli("info", tmp_path / "d")
    assert code == 1
    line = error_of(err)
    assert "internal error (RuntimeError: boom second line)" in line and "bug" in line


@pytest.mark.slow
def test_no_progress_fragments_on_a_pipe(tmp_path):
    code, out, err = run_cli("simulate", "--preset", "tiny", "--out", tmp_path / "s")
    # no bar on a pipe; only whole progress lines (one per 30 s: none on a quick run)
    assert code == 0 and "\r" not in err and all(l.startswith("simulate tiny: ") for l in err.splitlines())
    code, _, err = run_cli("info", tmp_path / "s" / "nonexistent.h5")
    assert err.count("\n") == 1


# ---- never accept absurd data silently ----------------------------------------------------------


def test_ipin_posi_latitude_out_of_range_is_refused(tmp_path):
    data = dict(seed("ipin2023"))
    rel = next(iter(data))
    lines = data[rel].splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith("POSI"))
    fields = lines[i].split(";")
    fields[3] = "95.0"
    lines[i] = ";".join(fields)
    materialise({rel: "\n".join(lines) + "\n"}, tmp_path / "src")
    code, _, err = run_cli("import", "ipin2023", tmp_path / "src", "--out", tmp_path / "o")
    assert code == 2 and "POSI" in error_of(err, "coordinates / repeated labels") and "out of range" in err


def test_ilc2_waypoint_off_the_floor_plan_is_refused(tmp_path):
    data = dict(seed("ilc2"))
    rel = next(iter(data))
    data[rel] = data[rel].replace("TYPE_WAYPOINT\t", "TYPE_WAYPOINT\t5000", 1)
    materialise(data, tmp_path / "src")
    code, _, err = run_cli("import", "ilc2", tmp_path / "src", "--out", tmp_path / "o")
    assert code == 2 and "outside" in error_of(err, "coordinates / repeated labels")


def test_uci_labels_twice_are_refused(tmp_path):
    data = dict(seed("uci-hapt"))
    data["RawData/labels.txt"] = data["RawData/labels.txt"] * 2
    materialise(data, tmp_path / "src")
    code, _, err = run_cli("import", "uci-hapt", tmp_path / "src", "--out", tmp_path / "o")
    assert code == 2 and "repeats row" in error_of(err, "coordinates / repeated labels")


def test_truncated_ilc2_trace_is_flagged_not_complete(tmp_path):
    data = dict(seed("ilc2"))
    rel = next(iter(data))
    text = data[rel]
    data[rel] = text[: int(len(text) * 0.7)]  # cut mid-line, footer gone
    materialise(data, tmp_path / "src")
    code, _, err = run_cli("import", "ilc2", tmp_path / "src", "--out", tmp_path / "o")
    assert code == 0
    (line,) = err.splitlines()
    assert line.startswith("warning: ") and "cut short" in line
    rec = Dataset.open(tmp_path / "o").load("trace")
    assert "endTime" in rec.meta["truncated"]
    OUTCOMES[("truncated ILC2 trace", "valid, flagged")] += 1
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        from wearnav.importers import ilc2

        list(ilc2.read(tmp_path / "src"))
    assert [w.category for w in caught] == [WearnavWarning]


def test_complete_ilc2_trace_is_not_flagged(tmp_path):
    materialise(seed("ilc2"), tmp_path / "src")
    from wearnav.importers import ilc2

    (rec,) = list(ilc2.read(tmp_path / "src"))
    assert "truncated" not in rec.meta


def test_help_and_no_arguments_are_not_errors():
    code, out, err = run_cli("--help")
    assert code == 0 and "import" in out and err == ""
    code, out, err = run_cli()
    assert code == 2 and "import" in out and err == ""


def test_ctrl_c_while_writing_is_one_line_and_leaves_nothing(tmp_path, monkeypatch):
    calls = []
    save = Recording.save

    def interrupted_save(self, path):
        calls.append(path)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return save(self, path)

    monkeypatch.setattr(Recording, "save", interrupted_save)
    code, _, err = run_cli("simulate", "--preset", "tiny", "--out", tmp_path / "sim")
    assert (
        code == 130
        and error_of(err)
        == f"error: interrupted; nothing was written to {tmp_path / 'sim'}; run the same command again"
    )
    assert list(tmp_path.iterdir()) == []


def test_uji_executions_missing_from_the_declared_count_are_flagged(tmp_path):
    data = dict(seed("uji-phone-watch"))
    data["DATA/subjects_info.csv"] = data["DATA/subjects_info.csv"].replace(
        "s01,54,M,190,83,R,1", "s01,54,M,190,83,R,6"
    )
    materialise(data, tmp_path / "src")
    code, _, err = run_cli("import", "uji-phone-watch", tmp_path / "src", "--out", tmp_path / "o")
    assert code == 0
    (line,) = err.splitlines()
    assert line.startswith("warning: ") and "s01 6 declared, 1 found" in line
    assert Dataset.open(tmp_path / "o").load("uji_s01_01").meta["executions_found"] == 1
    OUTCOMES[("incomplete UJI copy", "valid, flagged")] += 1


def test_unwritable_out_is_one_line(tmp_path, monkeypatch):
    import tempfile as tempfile_module

    def denied(*a, dir=None, **k):
        raise PermissionError(13, "Permission denied", str(dir))

    monkeypatch.setattr(tempfile_module, "mkdtemp", denied)  # a read-only folder, even for root
    code, _, err = run_cli("simulate", "--preset", "tiny", "--out", tmp_path / "ro" / "sim")
    assert code == 2 and error_of(err, "bad --out") == f"error: {tmp_path / 'ro'}: Permission denied"


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_folder_is_one_line(tmp_path):
    (tmp_path / "ro").mkdir()
    (tmp_path / "ro").chmod(0o500)
    try:
        code, _, err = run_cli("simulate", "--preset", "tiny", "--out", tmp_path / "ro" / "sim")
    finally:
        (tmp_path / "ro").chmod(0o700)
    assert code == 2 and "Permission denied" in error_of(err, "bad --out")


def test_pandas_parser_errors_are_one_line(tmp_path):
    data = dict(seed("uji-phone-watch"))
    rel = "DATA/s01/s01_01_sp.csv"
    lines = data[rel].splitlines()
    lines[50] += ",1,2,3"  # a row with extra fields: pandas' message spans two lines
    data[rel] = "\n".join(lines) + "\n"
    materialise(data, tmp_path / "src")
    code, _, err = run_cli("import", "uji-phone-watch", tmp_path / "src", "--out", tmp_path / "o")
    assert code == 2 and "Expected 8 fields" in error_of(err, "multi-line library message")
