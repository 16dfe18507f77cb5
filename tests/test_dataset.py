from pathlib import Path

import pandas as pd
import pytest

from conftest import make_stream
from wearnav.dataset import Dataset, DatasetWriter, write_subset
from wearnav.errors import FormatError, MissingFileError, ValidationError
from wearnav.recording import Recording


def _rec(name, subject, mode, devices=("phone", "watch")):
    return Recording(
        name,
        {d: make_stream(seed=i) for i, d in enumerate(devices)},
        meta={"subject": subject, "mode": mode, "placement": "HD"},
    )


@pytest.fixture
def ds(tmp_path):
    with DatasetWriter(tmp_path / "d") as w:
        w.add(_rec("a", "u1", "STW"), split="train")
        w.add(_rec("b", "u1", "PVW", ("phone",)), split="val")
        w.add(_rec("c", "u2", "STW", ("phone", "watch", "earbuds")), split="cross_subject")
    return Dataset.open(tmp_path / "d")


def test_manifest_and_load(ds):
    assert isinstance(ds.manifest, pd.DataFrame)
    assert ds.names == ["a", "b", "c"]
    assert ds.manifest.loc[0, "devices"] == "phone;watch"
    assert ds.manifest.loc[0, "duration"] == pytest.approx(1.99)
    assert ds.load("c").meta["subject"] == "u2"
    assert [r.name for r in ds] == ["a", "b", "c"]


def test_filters_and_splits(ds):
    assert ds.filter(mode="STW").names == ["a", "c"]
    assert ds.filter(subject=["u2"]).names == ["c"]
    assert ds.filter(devices=["phone", "watch"]).names == ["a", "c"]
    assert ds.filter(mode="STW", devices=["earbuds"]).names == ["c"]
    assert ds.split("train", "val").names == ["a", "b"]
    assert ds.split("train").filter(mode="PVW").names == []
    with pytest.raises(ValidationError, match="unknown split"):
        ds.split("nonsense")


def test_subset_keeps_the_matching_recordings_and_their_splits(ds, tmp_path):
    sub = write_subset(ds, tmp_path / "stw", {"made_by": "test"}, mode="STW")
    assert sub.names == ["a", "c"]
    assert dict(zip(sub.names, sub.manifest["split"], strict=True)) == {"a": "train", "c": "cross_subject"}
    assert sub.load("c").meta["subject"] == "u2" and len(sub.load("c").devices) == 3
    assert sub.provenance["mode"] == "STW" and sub.provenance["from"] == str(ds.root)


def test_summary(ds):
    s = ds.summary()
    assert s["recordings"] == 3 and s["devices"]["phone"] == 3 and s["modes"] == {"PVW": 1, "STW": 2}


def test_open_errors(tmp_path):
    with pytest.raises(MissingFileError):
        Dataset.open(tmp_path / "missing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(FormatError, match="manifest"):
        Dataset.open(tmp_path / "empty")


def test_duplicate_names_rejected(tmp_path):
    w = DatasetWriter(tmp_path / "d")
    w.add(_rec("a", "u1", "STW"))
    with pytest.raises(ValidationError, match="duplicate"):
        w.add(_rec("a", "u1", "STW"))


def test_failed_write_leaves_nothing_behind(tmp_path):
    with pytest.raises(RuntimeError):  # noqa: PT012  the raise inside the writer's block is the case under test
        with DatasetWriter(tmp_path / "d") as w:
            w.add(_rec("a", "u1", "STW"))
            raise RuntimeError("importer broke halfway")
    assert list(tmp_path.iterdir()) == []


def test_rewrite_replaces_a_dataset_but_never_a_foreign_folder(tmp_path, ds):
    with DatasetWriter(ds.root) as w:
        w.add(_rec("z", "u3", "DLW"))
    assert Dataset.open(ds.root).names == ["z"]
    assert not list(ds.root.glob("a.h5"))
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("precious")
    with pytest.raises(ValidationError, match="not a wearnav dataset"):
        DatasetWriter(tmp_path / "mine")


def test_provenance_is_saved_with_the_dataset(tmp_path):
    with DatasetWriter(tmp_path / "d", {"generator": "test", "seed": 7}) as w:
        w.add(_rec("a", "u1", "STW"))
    prov = Dataset.open(tmp_path / "d").provenance
    assert prov["generator"] == "test" and prov["seed"] == 7 and prov["recordings"] == 1
    assert prov["wearnav"] and prov["created"]


def test_a_written_dataset_is_on_disk_before_it_is_renamed_into_place(tmp_path, monkeypatch):
    """Manifest, dataset.yaml and recordings are fsynced, then the work folder, before the rename;
    the parent folder after it (a power cut leaves the old dataset or the whole new one)."""
    import os

    from wearnav import dataset as dataset_mod

    events = []
    real_replace = os.replace
    monkeypatch.setattr(dataset_mod, "fsync_file", lambda p: events.append(("file", Path(p).name)))
    monkeypatch.setattr(dataset_mod, "fsync_dir", lambda p: events.append(("dir", Path(p))))
    monkeypatch.setattr(
        dataset_mod.os, "replace", lambda a, b: (events.append(("rename", Path(b))), real_replace(a, b))[1]
    )
    with DatasetWriter(tmp_path / "d") as w:
        w.add(_rec("a", "u1", "STW"), split="train")
        w.add(_rec("b", "u2", "STW"), split="test")
        work = w.tmp
    # recordings' own atomic writes rename inside the work folder; the dataset's rename is last
    events = [e for e in events if not (e[0] == "rename" and e[1].parent == work)]
    files = {name for kind, name in events[:-3] if kind == "file"}
    assert files == {"a.h5", "b.h5", "manifest.csv", "dataset.yaml"}
    assert events[-3:] == [("dir", work), ("rename", tmp_path / "d"), ("dir", tmp_path)]


def _only(tmp_path, splits: dict[str, str]) -> Dataset:
    with DatasetWriter(tmp_path / "only") as w:
        for name, split in splits.items():
            w.add(_rec(name, "u1", "PVW", ("phone",)), split=split)
    return Dataset.open(tmp_path / "only")


def test_train_val_views_derive_validation_by_name_when_a_dataset_has_none(tmp_path):
    """1 in VAL_EVERY training recordings by a CRC-32 of the name (what bench real-odometry uses),
    whatever the order; the dataset's own val / validation split where it has one."""
    import zlib

    from wearnav.dataset import VAL_EVERY, is_validation_name, train_val_views

    names = [f"walk{i:02d}" for i in range(20)]
    train, val, note = train_val_views(_only(tmp_path, {n: "train" for n in names}), "train", "val")
    chosen = [n for n in names if zlib.crc32(n.encode()) % VAL_EVERY == 0]
    assert chosen and sorted(val.names) == chosen == [n for n in names if is_validation_name(n)]
    assert sorted(train.names) == [n for n in names if n not in chosen]
    assert note.startswith(f"no 'val' split in the dataset: validating on {len(chosen)} of its 20 'train' recordings")
    own = _only(tmp_path / "own", {"a": "train", "b": "train", "c": "validation"})
    assert [v.names for v in train_val_views(own, "train", "val")[:2]] == [["a", "b"], ["c"]]
    with pytest.raises(ValidationError, match=r"unknown split\(s\) \['trian'\]; valid: train"):
        train_val_views(_only(tmp_path / "t", {"a": "train"}), "trian", "val")
