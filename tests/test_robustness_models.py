"""Bad input to the model commands keeps the data layer's promises (issue 19 §2).

``train``, ``eval``, ``track``, ``classify``, ``label-from-fixes``, ``results`` and the ``bench``
suites, run as a user would (``cli.main`` in-process, or a real process for signals): bad input
is one ``error: FILE: reason`` line and exit 2, never an internal error; a refused call writes
nothing and leaves every file it did not write as it was; Ctrl-C is exit 130 and SIGTERM 143,
with the run folder resumable. One test per class of failure found, then hypothesis properties
over damaged run folders, config.yaml, results.json / results.md, ``--split`` lists and
``--test-routes`` patterns (outcomes counted with those of :mod:`test_robustness`).
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from conftest import make_stream
from test_robustness import OUTCOMES, PROPERTY, error_of, report_outcomes, run_cli, snapshot  # noqa: F401
from test_train_odometry import TinyGait  # noqa: F401  (registers "test-mlp")
from wearnav.dataset import Dataset, write_dataset
from wearnav.errors import FormatError, ValidationError
from wearnav.recording import DeviceStream, Fixes, Recording, Trajectory

# Examples per property: 20 (a few seconds each); WEARNAV_MODEL_EXAMPLES sets another count.
EXAMPLES = int(os.environ.get("WEARNAV_MODEL_EXAMPLES", "20"))
MODEL_PROPERTY = PROPERTY.__class__(PROPERTY, max_examples=EXAMPLES)


# ---- fixtures: a small dataset, a PDR run, a tiny learned run, a classifier run ------------------


@pytest.fixture(scope="module")
def tiny(tiny_dataset) -> Path:
    return tiny_dataset(1)


@pytest.fixture(scope="module")
def small(tiny, tmp_path_factory) -> Path:
    """Two training recordings (two walking modes), one validation and one test recording of
    ``tiny``: evaluations take a moment."""
    ds = Dataset.open(tiny)
    m = ds.manifest.set_index("name")
    split = m["split"]
    train = m[split == "train"].drop_duplicates("mode").index[:2].tolist()
    pick = train + [n for n in ds.names if split[n] == "val"][:1] + [n for n in ds.names if split[n] == "test"][:1]
    path = tmp_path_factory.mktemp("data") / "small"
    write_dataset(path, [(ds.load(n), split[n]) for n in pick])
    return path


@pytest.fixture(scope="module")
def pdr_run(small, tmp_path_factory) -> Path:
    run = tmp_path_factory.mktemp("runs") / "pdr"
    code, _, err = run_cli("train", "pdr", "--data", small, "--out", run)
    assert code == 0, err
    return run


@pytest.fixture(scope="module")
def clf_run(small, tmp_path_factory) -> Path:
    from wearnav.train.classify import ClassifyConfig, fit, prepare_run

    cfg = ClassifyConfig(
        model="har-cnn-bilstm",
        data=str(small),
        label_kind="mode",
        rate=25.0,
        window=50,
        stride=25,
        epochs=1,
        max_train_windows=32,
    )
    run = prepare_run(cfg, tmp_path_factory.mktemp("runs") / "clf")
    fit(cfg, run, progress=False)
    return run


def _refused(code: int, out: str, err: str, cls: str, needle: str = "") -> str:
    """The one error line of a refused call (exit 2, nothing on stdout), counted under ``cls``."""
    assert code == 2, (code, err)
    line = error_of(err, cls)
    assert "internal error" not in line and needle in line, line
    return line


# ---- signals during `train` ----------------------------------------------------------------------


@pytest.mark.parametrize(
    "signum, code, line",
    [(signal.SIGTERM, 143, "error: terminated (SIGTERM)"), (signal.SIGINT, 130, "error: interrupted")],
)
def test_signal_during_train_is_its_exit_code_and_the_run_resumes(signum, code, line, tiny, tmp_path, monkeypatch):
    from wearnav.train.common import SeededModule

    step = SeededModule.training_step
    sent = []

    def signalled_step(self, batch, batch_idx):  # the signal arrives in the second epoch's 2nd batch
        if self.current_epoch == 1 and batch_idx == 1 and not sent:
            sent.append(signum)
            os.kill(os.getpid(), signum)
        return step(self, batch, batch_idx)

    monkeypatch.setattr(SeededModule, "training_step", signalled_step)
    sigint = signal.getsignal(signal.SIGINT)
    args = (
        "train",
        "test-mlp",
        "--data",
        tiny,
        "--out",
        tmp_path / "run",
        "--epochs",
        "3",
        "--batch",
        "64",
        "--no-evaluate",
    )
    got, out, err = run_cli(*args)
    kept = f"; {tmp_path / 'run'} keeps the last finished epoch; run the same command again to resume"
    assert sent and (got, error_of(err, "signal during train")) == (code, line + kept)
    last = tmp_path / "run" / "checkpoints" / "last.ckpt"
    import torch

    assert torch.load(last, map_location="cpu", weights_only=False)["epoch"] == 0  # the last whole epoch
    assert not (tmp_path / "run" / "training.json").exists()
    assert signal.getsignal(signal.SIGINT) is sigint  # the handlers are given back
    monkeypatch.setattr(SeededModule, "training_step", step)
    got, out, err = run_cli(*args)
    assert got == 0, err
    record = json.loads((tmp_path / "run" / "training.json").read_text())
    assert record["resumed"] and record["attempts"] == 2 and record["epochs_run"] == 3


@pytest.mark.slow
def test_sigterm_to_a_training_process_is_143(small, tmp_path):
    """The real thing: Lightning's own SIGTERM handling in a process of its own."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parents[1] / "src"), "OMP_NUM_THREADS": "1"}
    out = tmp_path / "run"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "wearnav",
            "train",
            "ionet",
            "--data",
            str(small),
            "--out",
            str(out),
            "--epochs",
            "1000",
            "--no-evaluate",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    deadline = time.time() + 120
    while time.time() < deadline and not (out / "checkpoints" / "last.ckpt").is_file() and proc.poll() is None:
        time.sleep(0.1)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err
    assert error_of(err, "signal during train") == (
        f"error: terminated (SIGTERM); {out} keeps the last finished epoch; run the same command again to resume"
    )
    assert (out / "checkpoints" / "last.ckpt").is_file() and not (out / "training.json").exists()


# ---- internal errors that are bad input ----------------------------------------------------------


def test_train_refuses_a_classifier_model_and_writes_nothing(small, tmp_path):
    _refused(
        *run_cli("train", "har-cnn-bilstm", "--data", small, "--out", tmp_path / "run"),
        "internal errors",
        "is a classify model",
    )
    assert list(tmp_path.iterdir()) == []


def test_non_text_config_yaml_is_one_line(pdr_run, tmp_path):
    run = shutil.copytree(pdr_run, tmp_path / "run")
    (run / "config.yaml").write_bytes(b"\xff\xfe\x00\x81garbage")
    before = snapshot(tmp_path)
    _refused(*run_cli("eval", run), "internal errors", "config.yaml: not a UTF-8 text file")
    assert snapshot(tmp_path) == before


def test_non_text_results_md_is_one_line(tmp_path):
    (tmp_path / "suite").mkdir()
    (tmp_path / "suite" / "results.md").write_bytes(b"\x81\xff# not text")
    _refused(
        *run_cli("results", tmp_path / "suite", "--out", tmp_path / "docs" / "results.md"),
        "internal errors",
        "results.md: not a UTF-8 text file",
    )
    assert not (tmp_path / "docs").exists()


def test_corrupt_results_json_of_a_suite_is_one_line(tmp_path):
    (tmp_path / "har").mkdir()
    (tmp_path / "har" / "results.json").write_text('{"invocations": [')
    before = snapshot(tmp_path)
    _refused(
        *run_cli("bench", "har", "--out", tmp_path / "har", "--data", tmp_path, "--datasets", "uci-hapt"),
        "internal errors",
        "results.json: unreadable JSON",
    )
    assert snapshot(tmp_path) == before


def test_malformed_test_routes_is_one_line(small, tmp_path):
    _refused(
        *run_cli("bench", "easytrack", "--out", tmp_path / "et", "--data", small, "--test-routes", "(u1"),
        "internal errors",
        "--test-routes '(u1' is not a regular expression",
    )
    assert list(tmp_path.iterdir()) == []


# ---- a failed call writes nothing ----------------------------------------------------------------


def test_eval_checks_every_split_before_writing(pdr_run, tmp_path):
    run = shutil.copytree(pdr_run, tmp_path / "run")
    before = snapshot(tmp_path)
    _refused(*run_cli("eval", run, "--split", "test,nope"), "failed call writes first", "unknown split(s) ['nope']")
    assert snapshot(tmp_path) == before


def test_train_without_a_test_split_says_it_is_not_evaluated(small, tmp_path):
    """Training on data without a test split (an imported real dataset) trains, and says before
    training that it will not evaluate, naming the splits there are (issue 22 §2)."""
    ds = Dataset.open(small)
    split = ds.manifest.set_index("name")["split"]
    data = write_dataset(tmp_path / "notest", [(ds.load(n), split[n]) for n in ds.names if split[n] != "test"]).root
    code, out, err = run_cli("train", "test-mlp", "--data", data, "--out", tmp_path / "run", "--epochs", "1")
    assert code == 0, err
    assert "no 'test' split" in err and "not evaluated" in err and '"test"' not in out
    assert (tmp_path / "run" / "training.json").is_file() and not (tmp_path / "run" / "metrics.json").exists()


def test_results_touches_no_image_when_it_fails(tmp_path):
    suite = tmp_path / "s1"
    suite.mkdir()
    (suite / "a.png").write_bytes(b"new")
    (suite / "results.md").write_text("# T\n\n## A\n\n![a](a.png)\n![b](missing.png)\n")
    (tmp_path / "docs" / "img").mkdir(parents=True)
    (tmp_path / "docs" / "img" / "s1_a.png").write_bytes(b"old")
    before = snapshot(tmp_path / "docs")
    _refused(
        *run_cli("results", suite, "--out", tmp_path / "docs" / "results.md"),
        "failed call writes first",
        "links missing.png",
    )
    assert snapshot(tmp_path / "docs") == before


def test_classify_and_bench_har_leave_no_folder_when_they_fail(clf_run, tmp_path):
    _refused(
        *run_cli("classify", tmp_path / "missing.zip", "--model", clf_run, "--out", tmp_path / "lab"),
        "failed call writes first",
        "no such file",
    )
    _refused(
        *run_cli("bench", "har", "--out", tmp_path / "har", "--data", tmp_path / "nowhere", "--datasets", "uci-hapt"),
        "failed call writes first",
        "no uci-hapt source",
    )
    _refused(
        *run_cli("bench", "har", "--out", tmp_path / "har", "--techniques", "nonsense", "--quick"),
        "failed call writes first",
        "unknown technique(s)",
    )
    assert list(tmp_path.iterdir()) == []


def test_classify_writes_and_adds_with_its_marker(clf_run, small, tmp_path):
    ds = Dataset.open(small)
    h5 = [ds.path(n) for n in ds.names[:2]]
    code, out, err = run_cli("classify", h5[0], "--model", clf_run, "--out", tmp_path / "lab")
    assert code == 0, err
    code, out, err = run_cli("classify", h5[1], "--model", clf_run, "--out", tmp_path / "lab")
    assert code == 0, err
    names = sorted(p.name for p in (tmp_path / "lab").iterdir())
    assert names == sorted(
        ["classify.json"] + [f"{n}_{k}" for n in ds.names[:2] for k in ("intervals.csv", "timeline.png")]
    )


# ---- files the user owns -------------------------------------------------------------------------


def test_track_never_replaces_a_file_it_did_not_write(pdr_run, small, tmp_path):
    rec = Dataset.open(small).path(Dataset.open(small).names[0])
    out = tmp_path / "mine"
    out.mkdir()
    (out / "trajectory.csv").write_text("my own\n")
    _refused(
        *run_cli("track", rec, "--model", pdr_run, "--out", out),
        "user files",
        "holds trajectory.csv, which `wearnav track` did not write",
    )
    assert (out / "trajectory.csv").read_text() == "my own\n" and len(list(out.iterdir())) == 1
    # its own folder is replaced as a whole, again and again
    for _ in range(2):
        code, _, err = run_cli("track", rec, "--model", pdr_run, "--out", tmp_path / "t")
        assert code == 0, err
    assert sorted(p.name for p in (tmp_path / "t").iterdir()) == [
        "fixes.csv",
        "track.json",
        "trajectory.csv",
        "trajectory.html",
        "trajectory.png",
    ]
    # a failed track into a new folder leaves none
    _refused(
        *run_cli("track", tmp_path / "nothing.h5", "--model", pdr_run, "--out", tmp_path / "new" / "t"),
        "user files",
        "no such file",
    )
    assert not (tmp_path / "new").exists()


# ---- nothing silent ------------------------------------------------------------------------------


def test_devices_no_recording_has_are_refused(small, tmp_path):
    _refused(
        *run_cli("train", "pdr", "--data", small, "--out", tmp_path / "run", "--devices", "phone,wach"),
        "silent",
        "unknown device(s) ['wach']",
    )
    assert list(tmp_path.iterdir()) == []


def _without(path: Path, src: Path, change) -> Path:
    ds = Dataset.open(src)
    split = ds.manifest.set_index("name")["split"]
    return write_dataset(path, [(change(ds.load(n)), split[n]) for n in ds.names]).root


def test_bench_odometry_without_truth_writes_no_page(small, tmp_path):
    data = _without(tmp_path / "notruth", small, lambda r: dataclasses.replace(r, truth=None))
    _refused(
        *run_cli("bench", "odometry", "--data", data, "--out", tmp_path / "suite", "--models", "pdr"),
        "silent",
        "no recording of split 'test' has truth positions",
    )
    assert not (tmp_path / "suite").exists()


def test_label_from_fixes_at_one_point_is_not_silent(small, tmp_path):
    def stuck(rec):
        return dataclasses.replace(rec, fixes=Fixes(rec.fixes.t, np.zeros_like(rec.fixes.pos), rec.fixes.accuracy))

    data = _without(tmp_path / "stuck", small, stuck)
    code, out, err = run_cli("label-from-fixes", data, "--out", tmp_path / "lab")
    lines = err.splitlines()
    assert code == 2 and not out and lines[-1].startswith("error: no recording gave a labelled segment")
    assert sum("lie at one point" in ln and ln.startswith("warning: ") for ln in lines) == 4
    assert not (tmp_path / "lab").exists()


# ---- data-layer leftovers ------------------------------------------------------------------------


def test_manifest_devices_must_match_the_recording(small, tmp_path):
    d = shutil.copytree(small, tmp_path / "d")
    m = pd.read_csv(d / "manifest.csv", dtype=str, keep_default_na=False)
    m.loc[0, "devices"] = "phone"
    m.to_csv(d / "manifest.csv", index=False)
    with pytest.raises(FormatError, match=r"holds devices \['earbuds', 'phone', 'watch'\], but the manifest lists"):
        Dataset.open(d).load(m.loc[0, "name"])


@pytest.mark.parametrize("worn", [np.full(200, 0.5), np.full(200, 2), np.array(["no"] * 200)])
def test_worn_must_be_boolean(worn):
    s = make_stream(n=200)
    with pytest.raises(ValidationError, match="worn: not booleans"):
        DeviceStream(s.t, s.acc, s.gyro, worn=worn)
    assert DeviceStream(s.t, s.acc, worn=np.r_[np.ones(100), np.zeros(100)]).worn.dtype == bool


def test_truth_floor_must_be_finite():
    with pytest.raises(ValidationError, match="truth.floor: non-finite"):
        Trajectory(np.arange(5.0), np.zeros((5, 2)), floor=np.r_[0.0, np.nan, 0, 0, 0])


def test_align_refuses_a_span_shorter_than_one_sample():
    from wearnav.preprocess import PreprocessConfig, align

    s = make_stream(n=2, rate=100.0)  # 10 ms: less than one 40 ms tick at 25 Hz
    rec = Recording("a", {"phone": s}, truth=Trajectory(s.t, np.zeros((2, 2))))
    with pytest.raises(ValidationError, match="shorter than one sample period at 25 Hz"):
        align(rec, PreprocessConfig(devices=("phone",)))


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_integrating_non_finite_velocities_is_refused(bad):
    from wearnav.trajectory import integrate_velocity

    vel = np.ones((5, 2))
    vel[2, 1] = bad
    with pytest.raises(ValidationError, match="not finite"):
        integrate_velocity(np.arange(5.0), vel, np.arange(5.0), np.zeros(2))


@pytest.mark.parametrize("labels", ["garbage", 5, {"start": 1}, [(0, 1, "mode")], pd.DataFrame({"x": [1]})])
def test_labels_replaced_after_construction_are_refused_on_save(labels, tmp_path):
    rec = Recording("a", {"phone": make_stream(n=50)})
    rec.labels = labels
    with pytest.raises(ValidationError, match="^labels: "):
        rec.save(tmp_path / "a.h5")
    assert list(tmp_path.iterdir()) == []


# ---- properties: whatever the damage, exit 0 or one line and exit 2, nothing written on failure --


def _outcome(code: int, out: str, err: str, cls: str, before: dict, root: Path) -> str:
    lines = err.splitlines()
    if code == 0:
        assert all(ln.startswith("warning: ") for ln in lines), err
        OUTCOMES[(cls, "valid")] += 1
        return "valid"
    assert code == 2, (code, err)
    line = error_of(err, cls)
    assert "internal error" not in line
    assert snapshot(root) == before, "a refused call changed files"
    return "error"


TEXT = st.one_of(st.text(max_size=60), st.binary(max_size=60).map(lambda b: b.decode("latin-1")))
YAML_VALUES = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-3, 300),
    st.floats(allow_nan=True),
    st.text(max_size=8),
    st.lists(st.text(max_size=4), max_size=3),
    st.dictionaries(st.text(max_size=4), st.integers(), max_size=2),
)
TRAIN_KEYS = [
    "model",
    "data",
    "devices",
    "model_args",
    "train_split",
    "val_split",
    "rate",
    "window",
    "stride",
    "epochs",
    "patience",
    "lr",
    "batch",
    "augment",
    "seed",
    "frame_align",
    "truth_max_gap",
    "yaw_deg",
    "no_such_key",
]
CLASSIFY_KEYS = [
    "model",
    "devices",
    "frame",
    "rate",
    "window",
    "stride",
    "label_kind",
    "classes",
    "denoise",
    "expand",
    "model_args",
    "no_such_key",
]


def _damage(run: Path, how: str, which: float, data, raw: bytes, keys=TRAIN_KEYS) -> None:
    files = sorted(p for p in run.rglob("*") if p.is_file())
    target = files[int(which * len(files))]
    if how == "delete":
        target.unlink()
    elif how == "truncate":
        target.write_bytes(target.read_bytes()[: int(which * target.stat().st_size)])
    elif how == "garbage":
        target.write_bytes(raw)
    elif how == "config field":
        doc = yaml.safe_load((run / "config.yaml").read_text())
        key = data.draw(st.sampled_from(keys))
        doc["config"]["train"][key] = data.draw(YAML_VALUES)
        (run / "config.yaml").write_text(yaml.safe_dump(doc))
    elif how == "config text":
        (run / "config.yaml").write_text(data.draw(TEXT), encoding="utf-8", errors="surrogatepass")


@pytest.mark.slow
def test_damaged_run_folders_are_evaluated_or_one_line(pdr_run, small):
    @MODEL_PROPERTY
    @given(
        how=st.sampled_from(["delete", "truncate", "garbage", "config field", "config field", "config text"]),
        which=st.floats(0, 1, exclude_max=True),
        raw=st.binary(max_size=40),
        data=st.data(),
    )
    def prop(how, which, raw, data):
        with tempfile.TemporaryDirectory() as tmp:
            run = shutil.copytree(pdr_run, Path(tmp) / "run")
            if data.draw(st.booleans()):
                (run / "metrics.json").unlink()
            _damage(run, how, which, data, raw)
            before = snapshot(Path(tmp))
            _outcome(*run_cli("eval", run), f"damaged run folder ({how})", before, Path(tmp))
            before = snapshot(Path(tmp))
            _outcome(
                *run_cli("track", rec, "--model", run, "--out", Path(tmp) / "track"),
                f"track with a damaged run ({how})",
                before,
                Path(tmp),
            )

    rec = Dataset.open(small).path(Dataset.open(small).names[0])
    prop()


def test_damaged_classifier_runs_classify_or_one_line(clf_run, small):
    rec = Dataset.open(small).path(Dataset.open(small).names[0])

    @MODEL_PROPERTY
    @given(
        how=st.sampled_from(["delete", "truncate", "garbage", "config field", "config field", "config text"]),
        which=st.floats(0, 1, exclude_max=True),
        raw=st.binary(max_size=40),
        data=st.data(),
    )
    def prop(how, which, raw, data):
        with tempfile.TemporaryDirectory() as tmp:
            run = shutil.copytree(clf_run, Path(tmp) / "run")
            _damage(run, how, which, data, raw, CLASSIFY_KEYS)
            before = snapshot(Path(tmp))
            _outcome(
                *run_cli("classify", rec, "--model", run, "--out", Path(tmp) / "lab"),
                f"classify with a damaged run ({how})",
                before,
                Path(tmp),
            )

    prop()


def test_split_lists_are_evaluated_or_one_line(pdr_run):
    names = ["test", "val", "train", "nope", "", " ", "test ", "TEST", "../x", "a\nb"]

    @MODEL_PROPERTY
    @given(splits=st.lists(st.sampled_from(names), max_size=4))
    def prop(splits):
        with tempfile.TemporaryDirectory() as tmp:
            run = shutil.copytree(pdr_run, Path(tmp) / "run")
            before = snapshot(Path(tmp))
            _outcome(*run_cli("eval", run, "--split", ",".join(splits)), "--split lists", before, Path(tmp))

    prop()


def test_results_pages_and_suite_json_are_used_or_one_line(tmp_path):
    @MODEL_PROPERTY
    @given(
        page=st.one_of(TEXT, st.just("## A\n![x](a.png)\n"), st.just("## A\n![x](../a.png)\n")),
        raw=st.one_of(st.none(), st.binary(max_size=40)),
        results_json=st.one_of(TEXT, st.just('{"invocations": 3}'), st.just("[1, 2]"), st.just('{"invocations": [1]}')),
    )
    def prop(page, raw, results_json):
        with tempfile.TemporaryDirectory() as tmp:
            root = Path(tmp)
            suite = root / "suite"
            suite.mkdir()
            (suite / "a.png").write_bytes(b"png")
            if raw is None:
                (suite / "results.md").write_text(page, encoding="utf-8", errors="surrogatepass")
            else:
                (suite / "results.md").write_bytes(raw)
            (suite / "results.json").write_text(results_json, encoding="utf-8", errors="surrogatepass")
            (root / "docs").mkdir()
            before = snapshot(root)
            _outcome(*run_cli("results", suite, "--out", root / "docs" / "results.md"), "results.md", before, root)
            before = snapshot(root)
            # results.json is read first: garbage is one line; a readable one meets the unknown dataset
            code, out, err = run_cli("bench", "har", "--out", suite, "--data", root, "--datasets", "nope")
            assert _outcome(code, out, err, "suite results.json", before, root) == "error"

    prop()


def test_test_routes_patterns_are_one_line(small, tmp_path_factory):
    one = tmp_path_factory.mktemp("data") / "one"
    ds = Dataset.open(small)
    write_dataset(one, [(ds.load(ds.names[0]), "")])  # one recording: no pattern leaves a training route

    @MODEL_PROPERTY
    @given(pattern=st.one_of(st.text(max_size=12), st.sampled_from(["(", "[a-", "*", "a{2,1}", "(?P<x", "\\"])))
    def prop(pattern):
        with tempfile.TemporaryDirectory() as tmp:
            before = snapshot(Path(tmp))
            code, out, err = run_cli(
                "bench", "easytrack", "--out", Path(tmp) / "et", "--data", one, "--test-routes", pattern, "--quick"
            )
            assert _outcome(code, out, err, "--test-routes", before, Path(tmp)) == "error"

    prop()
