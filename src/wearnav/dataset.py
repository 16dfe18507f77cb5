"""Dataset folders: ``*.h5`` recordings plus ``manifest.csv`` (one row per recording).

Write with :class:`DatasetWriter` (the simulator and every importer do), read with
:meth:`Dataset.open`. A Dataset is an immutable view of a manifest: :meth:`Dataset.filter` and
:meth:`Dataset.split` return narrower views of the same folder.

The manifest columns are ``name, file, duration, devices, mode, subject, placement, scene,
source, split, noise_level, truth_points, fixes``, taken from each recording's meta;
``devices`` is a ``;``-joined list of device names and ``noise_level`` the location-fix noise
level of simulated data (EasyTrack's L1/L2/L3).

Decision: docs/decisions/0038-mse-heading-frame-and-sim-hd.md.
"""

from __future__ import annotations

import csv
import os
import re
import shutil
import signal
import tempfile
import threading
import zlib
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from types import FrameType
from typing import Any

import numpy as np
import pandas as pd
import yaml

from wearnav.core.fileio import fsync_dir, fsync_file, host_tag, pid_alive, require_regular_file
from wearnav.core.interrupts import noting_lost_interrupts, raise_lost_interrupt
from wearnav.core.provenance import provenance
from wearnav.core.textio import read_yaml
from wearnav.errors import FormatError, MissingFileError, Terminated, ValidationError, check_names
from wearnav.recording import Recording
from wearnav.recording.checks import check_name, check_text

MANIFEST = "manifest.csv"
PROVENANCE = "dataset.yaml"
FORMAT_NAME = "wearnav.dataset"
# A dataset without a validation split validates on 1 in VAL_EVERY of its training recordings, chosen
# by a CRC-32 of the name (:func:`derived_validation`): the same on every machine and in any order.
VAL_EVERY = 5
VALIDATION_SPLITS = ("val", "validation")  # the names a dataset's own validation split goes by
FORMAT_VERSION = 1  # of the folder layout (manifest columns, dataset.yaml); 0 = before it was written
MANIFEST_COLUMNS = [
    "name",
    "file",
    "duration",
    "devices",
    "mode",
    "subject",
    "placement",
    "scene",
    "source",
    "split",
    "noise_level",
    "truth_points",
    "fixes",
]


def manifest_row(rec: Recording, file: str, split: str = "") -> dict:
    row = {
        "name": rec.name,
        "file": file,
        "duration": round(rec.duration, 3),
        "devices": ";".join(rec.devices),
        "mode": rec.meta.get("mode", ""),
        "subject": rec.meta.get("subject", ""),
        "placement": rec.meta.get("placement", ""),
        "scene": rec.meta.get("scene", ""),
        "source": rec.meta.get("source", ""),
        "split": split or rec.meta.get("split", ""),
        "noise_level": rec.meta.get("noise_level", ""),
        "truth_points": 0 if rec.truth is None else len(rec.truth),
        "fixes": 0 if rec.fixes is None else len(rec.fixes),
    }
    return row


def _work_dir_re(root: Path) -> re.Pattern:
    """Hidden siblings a writer of ``root`` makes: ``.<name>.<host>.<pid>.<random>.partial`` (being
    written) and ``.old`` (the dataset being replaced, for the instant between two renames)."""
    return re.compile(rf"^\.{re.escape(root.name)}\.(?P<host>[^.]*)\.(?P<pid>\d+)\.[^.]+\.(?P<kind>partial|old)$")


def clean_stale_work_dirs(root: Path) -> list[Path]:
    """Remove the work folders that writers of ``root`` on this host left when they died (kill -9,
    power loss); an ``.old`` copy whose replacement never landed is moved back to ``root``."""
    pattern, host = _work_dir_re(root), host_tag()
    cleaned: list[Path] = []
    try:
        siblings = list(root.parent.iterdir())
    except OSError:
        return cleaned
    for p in sorted(siblings):
        m = pattern.match(p.name)
        if not m or m["host"] != host or pid_alive(int(m["pid"])):
            continue
        if m["kind"] == "old" and not (root.exists() or root.is_symlink()):
            os.replace(p, root)
        else:
            shutil.rmtree(p, ignore_errors=True)
        cleaned.append(p)
    return cleaned


def replaceable_reason(root: Path) -> str | None:
    """Why ``root`` must not be replaced by a new dataset (None: it may be).

    Only a folder that is absent, empty, or a dataset wearnav wrote (its ``dataset.yaml`` says so)
    holding nothing but wearnav's files may be replaced; never the working folder or one above it.
    """
    try:
        resolved = root.resolve()
    except OSError as exc:
        return f"cannot resolve ({exc.strerror or exc})"
    cwd = Path.cwd().resolve()
    if root.name in ("", ".", "..") or resolved == cwd or resolved in cwd.parents:
        return "is the working folder or one above it; give a new folder for the dataset"
    if not (root.exists() or root.is_symlink()):
        return None
    if not root.is_dir():
        return "exists and is not a folder; not overwriting it"
    entries = list(root.iterdir())
    if not entries:
        return None
    made_by = _read_yaml(root / PROVENANCE) if (root / PROVENANCE).is_file() else None
    if not _written_by_wearnav(made_by):
        return "exists and is not a wearnav dataset (no dataset.yaml saying wearnav wrote it); not overwriting it"
    foreign = sorted(
        e.name for e in entries if not (e.name in (MANIFEST, PROVENANCE) or (e.suffix == ".h5" and e.is_file()))
    )
    if foreign:
        return f"holds files wearnav did not write ({', '.join(foreign[:3])}); not overwriting it"
    return None


def _written_by_wearnav(info) -> bool:
    if not isinstance(info, dict):
        return False
    # Folders written before the format key existed carry the package version and a time.
    return info.get("format") == FORMAT_NAME or ("wearnav" in info and "created" in info)


def _read_yaml(path: Path):
    return read_yaml(path, kind=None)


class DatasetWriter:
    """Writes recordings into a new dataset folder, all or nothing, never losing a user's files.

    Recordings go to a hidden sibling folder ``.<name>.<host>.<pid>.<random>.partial``;
    :meth:`close` writes the manifest and ``dataset.yaml`` (the format and its version, what made
    the dataset: ``provenance`` given by the caller, e.g. the simulator preset and seed or the
    importer and source, plus package version, commit and time) and renames that folder to
    ``root``. An earlier dataset at ``root`` is replaced by renames (it is moved aside, the new
    one moved in, then the old one removed), and only if wearnav wrote it
    (:func:`replaceable_reason`); any other existing folder is refused before anything is written.

    An exception inside the ``with`` block — and SIGTERM, turned into :class:`Terminated` while
    the block runs in the main thread (also when a finalizer swallowed it: :mod:`wearnav.core.interrupts`)
    — removes the partial folder, so a failed or stopped import
    or simulation leaves nothing behind. Work folders of writers killed outright (SIGKILL) are
    removed by the next writer of the same ``root`` (:func:`clean_stale_work_dirs`).

    >>> with DatasetWriter("out") as w:
    ...     w.add(rec, split="train")
    """

    def __init__(self, root: str | Path, provenance: dict | None = None):
        self.root = Path(root)
        self.provenance = dict(provenance or {})
        reason = replaceable_reason(self.root)
        if reason:
            raise ValidationError(reason, self.root)
        for parent in self.root.parents:
            if parent.exists():
                if not parent.is_dir():
                    raise ValidationError("is a file, so the dataset folder cannot be made inside it", parent)
                break
        self.root.parent.mkdir(parents=True, exist_ok=True)
        clean_stale_work_dirs(self.root)
        prefix = f".{self.root.name}.{host_tag()}.{os.getpid()}."
        self.tmp = Path(tempfile.mkdtemp(prefix=prefix, suffix=".partial", dir=self.root.parent))
        self.rows: list[dict] = []
        self._old_handler: Callable[[int, FrameType | None], Any] | int | None = None  # signal.signal's
        self._noting = noting_lost_interrupts()
        self._deferred = False  # SIGTERM arrived while the renames in close() ran
        self._critical = False

    def add(self, rec: Recording, split: str = "") -> None:
        raise_lost_interrupt()  # a SIGTERM whose exception a finalizer swallowed (wearnav.core.interrupts)
        if any(r["name"] == rec.name for r in self.rows):
            raise ValidationError(f"duplicate recording name {rec.name!r}", self.root)
        file = f"{rec.name}.h5"
        row = manifest_row(rec, file, split)
        for key, value in row.items():
            if isinstance(value, str):
                check_text(value, f"recording {rec.name!r}: manifest {key}")
        rec.save(self.tmp / file)
        self.rows.append(row)

    def close(self) -> Path:
        """Write the manifest and move the finished dataset into place; returns ``root``."""
        raise_lost_interrupt()
        df = pd.DataFrame(self.rows)
        for col in MANIFEST_COLUMNS:
            if col not in df.columns:
                df[col] = pd.Series(dtype=object)
        # Every cell quoted: a bare carriage return in a name or a meta value would otherwise
        # end the row when the manifest is read back.
        df[MANIFEST_COLUMNS].to_csv(self.tmp / MANIFEST, index=False, quoting=csv.QUOTE_ALL)
        info = {
            "format": FORMAT_NAME,
            "format_version": FORMAT_VERSION,
            **self.provenance,
            **provenance(),
            "recordings": len(self.rows),
        }
        (self.tmp / PROVENANCE).write_text(yaml.safe_dump(info, sort_keys=False), encoding="utf-8")
        # On disk before the folder is renamed into place, so that a power cut leaves the old
        # dataset or the whole new one (manifest and recordings), never a manifest naming empty files.
        for entry in self.tmp.iterdir():
            fsync_file(entry)
        fsync_dir(self.tmp)
        reason = replaceable_reason(self.root)  # again: the folder may have changed meanwhile
        if reason:
            raise ValidationError(reason, self.root)
        old = None
        self._critical = True  # a SIGTERM now waits until root is whole again
        try:
            if self.root.exists() or self.root.is_symlink():
                old = self.tmp.with_name(self.tmp.name[: -len(".partial")] + ".old")
                os.replace(self.root, old)
            try:
                os.replace(self.tmp, self.root)
            except BaseException:
                if old is not None:
                    os.replace(old, self.root)
                raise
        finally:
            self._critical = False
        fsync_dir(self.root.parent)  # the rename itself
        if old is not None:
            if old.is_symlink():
                old.unlink()
            else:
                shutil.rmtree(old, ignore_errors=True)
        if self._deferred:
            raise Terminated("terminated (SIGTERM) after the dataset was written")
        return self.root

    def abort(self) -> None:
        shutil.rmtree(self.tmp, ignore_errors=True)

    def _on_sigterm(self, signum, frame) -> None:
        if self._critical:
            self._deferred = True
            return
        raise Terminated("terminated (SIGTERM); the partial dataset was removed")

    def __enter__(self) -> DatasetWriter:
        if threading.current_thread() is threading.main_thread():
            self._old_handler = signal.signal(signal.SIGTERM, self._on_sigterm)
            self._noting.__enter__()
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            if exc_type is None:
                try:
                    self.close()
                except BaseException:
                    self.abort()
                    raise
            else:
                self.abort()
        finally:
            if self._old_handler is not None:
                signal.signal(signal.SIGTERM, self._old_handler)
                self._old_handler = None
                self._noting.__exit__(None, None, None)


class Dataset:
    """A view of a dataset folder: ``manifest`` (DataFrame), ``load(name)``, filters and splits."""

    def __init__(self, root: Path, manifest: pd.DataFrame):
        self.root = root
        self.manifest = manifest.reset_index(drop=True)

    @classmethod
    def open(cls, root: str | Path) -> Dataset:
        """Open a dataset folder, checking the manifest against the folder.

        Every manifest cell is read as text (names like ``001``, ``0`` or ``null`` stay names);
        names and files must be unique, every file listed must be there and every recording
        there must be listed; numbers must be numbers; the format version in ``dataset.yaml``
        must be one this wearnav reads.
        """
        root = Path(root)
        if not root.is_dir():
            raise MissingFileError("no such dataset folder", root)
        path = root / MANIFEST
        if not path.exists():
            raise FormatError(f"not a wearnav dataset (no {MANIFEST})", root)
        require_regular_file(path)
        if (root / PROVENANCE).exists():
            require_regular_file(root / PROVENANCE)
            _check_format(_read_yaml(root / PROVENANCE), root / PROVENANCE)
        try:
            df = pd.read_csv(path, dtype=str, keep_default_na=False, na_filter=False)
        except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, ValueError) as exc:
            raise FormatError(f"unreadable manifest ({exc})", path) from None
        missing = [c for c in ("name", "file", "duration", "devices") if c not in df.columns]
        if missing:
            raise FormatError(f"manifest lacks columns {missing}", path)
        for col in MANIFEST_COLUMNS:
            if col not in df.columns:
                df[col] = ""
        _check_manifest(df, root, path)
        df["duration"] = _numbers(df, "duration", float, path)
        for col in ("truth_points", "fixes"):
            df[col] = _numbers(df, col, int, path)
        return cls(root, df)

    @property
    def provenance(self) -> dict:
        """Contents of ``dataset.yaml`` (empty for folders written before it existed)."""
        path = self.root / PROVENANCE
        if not path.exists():
            return {}
        return _read_yaml(path) or {}

    # ---- views --------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.manifest)

    @property
    def names(self) -> list[str]:
        return self.manifest["name"].tolist()

    def _view(self, mask) -> Dataset:
        return Dataset(self.root, self.manifest[mask])

    def filter(self, mode=None, subject=None, placement=None, devices=None, source=None, noise_level=None) -> Dataset:
        """Keep recordings matching every given criterion.

        Each of ``mode``, ``subject``, ``placement``, ``source``, ``noise_level`` is a value or a
        list of values;
        ``devices`` is a list of device names that must all be present.
        """
        m = self.manifest
        mask = pd.Series(True, index=m.index)
        for col, want in (
            ("mode", mode),
            ("subject", subject),
            ("placement", placement),
            ("source", source),
            ("noise_level", noise_level),
        ):
            if want is not None:
                want = [want] if isinstance(want, str | int) else list(want)
                mask &= m[col].isin([str(w) for w in want])
        if devices is not None:
            need = set([devices] if isinstance(devices, str) else devices)
            mask &= m["devices"].map(lambda s: need <= set(s.split(";")))
        return self._view(mask)

    def split(self, *names: str) -> Dataset:
        """Recordings whose ``split`` is one of ``names`` (e.g. ``split("test", "test_unseen")``)."""
        check_names(names, sorted(set(self.manifest["split"])), "split", self.root, ValidationError)
        return self._view(self.manifest["split"].isin(names))

    def names_line(self, shown: int = 10) -> str:
        """The recordings' names for a message: ``a, b, c, ... (44 recordings)``."""
        names = self.names
        more = ", ..." if len(names) > shown else ""
        return f"{', '.join(names[:shown])}{more} ({len(names)} recording{'s' * (len(names) != 1)})"

    # ---- loading ------------------------------------------------------------------------
    def path(self, name: str) -> Path:
        rows = self.manifest[self.manifest["name"] == name]
        if rows.empty:
            raise ValidationError(f"no recording named {name!r}; it holds {self.names_line()}", self.root)
        return self.root / rows["file"].iloc[0]

    def load(self, name: str) -> Recording:
        path = self.path(name)
        rec = Recording.load(path)
        if rec.name != name:
            raise FormatError(f"holds recording {rec.name!r}, but the manifest lists it as {name!r}", path)
        listed = self.manifest.loc[self.manifest["name"] == name, "devices"].iloc[0]
        listed = sorted(d for d in str(listed).split(";") if d) if isinstance(listed, str) else []
        if listed != sorted(rec.devices):
            raise FormatError(
                f"holds devices {sorted(rec.devices)}, but the manifest lists {listed} "
                f"(filters and training layouts read the manifest)",
                path,
            )
        return rec

    def __iter__(self) -> Iterator[Recording]:
        for name in self.names:
            yield self.load(name)

    def summary(self) -> dict:
        """Counts and totals for ``wearnav info``."""
        m = self.manifest

        def counts(col: str) -> dict:
            return {k: int(v) for k, v in m[col].value_counts().sort_index().items() if k != ""}

        devs: dict[str, int] = {}
        for s in m["devices"]:
            for d in s.split(";"):
                devs[d] = devs.get(d, 0) + 1
        return {
            "root": str(self.root),
            "recordings": len(m),
            "total_duration_h": round(float(m["duration"].sum()) / 3600, 3),
            "devices": devs,
            "modes": counts("mode"),
            "subjects": counts("subject"),
            "placements": counts("placement"),
            "splits": counts("split"),
            "sources": counts("source"),
            "with_truth": int((m["truth_points"].fillna(0) > 0).sum()),
            "with_fixes": int((m["fixes"].fillna(0) > 0).sum()),
        }


def _check_format(info, path: Path) -> None:
    if not isinstance(info, dict):
        raise FormatError("not a mapping of keys to values", path)
    if "format" in info and info["format"] != FORMAT_NAME:
        raise FormatError(f"format {info['format']!r} is not {FORMAT_NAME!r}", path)
    version = info.get("format_version", 1 if "format" in info else 0)
    if not isinstance(version, int) or isinstance(version, bool) or not 0 <= version <= FORMAT_VERSION:
        raise FormatError(
            f"format_version {version!r} is not one this wearnav reads "
            f"(0..{FORMAT_VERSION}); written by a newer wearnav?",
            path,
        )


def _check_manifest(df: pd.DataFrame, root: Path, path: Path) -> None:
    for i, (name, file) in enumerate(zip(df["name"], df["file"]), 2):
        try:
            check_name(name, "recording name")
        except ValidationError as exc:
            raise FormatError(f"line {i}: {exc.reason}", path) from None
        if file != Path(file).name or not file.endswith(".h5") or file in (".h5",):
            raise FormatError(f"line {i}: file {file!r} is not a .h5 file name in the folder", path)
    for col in ("name", "file"):
        dup = df[col][df[col].duplicated()]
        if len(dup):
            raise FormatError(f"{col} {dup.iloc[0]!r} is listed more than once", path)
    present = {p.name for p in root.glob("*.h5")}
    absent = sorted(set(df["file"]) - present)
    if absent:
        raise FormatError(f"lists {len(absent)} file(s) that are not in the folder ({', '.join(absent[:3])})", path)
    unlisted = sorted(present - set(df["file"]))
    if unlisted:
        raise FormatError(
            f"{len(unlisted)} recording file(s) in the folder are not listed ({', '.join(unlisted[:3])})", path
        )


def _numbers(df: pd.DataFrame, col: str, kind: type, path: Path) -> pd.Series:
    text = df[col].str.strip()
    if kind is int:
        text = text.replace("", "0")  # counts written empty by hand mean none
    values = pd.to_numeric(text, errors="coerce")
    bad = values.isna() | ~np.isfinite(values.astype(float)) | (values < 0)
    if kind is int:
        bad |= values.astype(float) % 1 != 0
    if bad.any():
        i = int(np.argmax(bad.to_numpy()))
        raise FormatError(
            f"line {i + 2}: {col} {df[col].iloc[i]!r} is not a "
            f"{'non-negative integer' if kind is int else 'non-negative number'}",
            path,
        )
    return values.astype(kind)


def write_dataset(
    root: str | Path, recordings: Iterable[tuple[Recording, str]], provenance: dict | None = None
) -> Dataset:
    """Write (recording, split) pairs to ``root`` and open the result."""
    with DatasetWriter(root, provenance) as w:
        for rec, split in recordings:
            w.add(rec, split)
    return Dataset.open(root)


def write_subset(src: Dataset, root: str | Path, provenance: dict | None = None, **want) -> Dataset:
    """The recordings of ``src`` that :meth:`Dataset.filter` keeps for ``want`` written to ``root``,
    each with its split (e.g. the simulator's hand-held walks alone: ``placement="HD"``)."""
    split = dict(zip(src.manifest["name"], src.manifest["split"], strict=True))
    view = src.filter(**want)
    meta = {"from": str(src.root), **{k: v for k, v in want.items() if v is not None}, **(provenance or {})}
    return write_dataset(root, ((src.load(name), split[name]) for name in view.names), meta)


def scorable_split(ds, split: str):
    """``ds``'s split ``split``, refused when it is unknown, empty, or has no recording with truth
    to score against (metrics over 0 sequences would be a page of blanks)."""
    view = ds.split(split)
    if len(view) == 0:
        raise ValidationError(
            f"split {split!r} is empty (splits here: {sorted(set(ds.manifest['split'].astype(str)))})", ds.root
        )
    if (
        "truth_points" in view.manifest
        and (pd.to_numeric(view.manifest["truth_points"], errors="coerce").fillna(0) < 2).all()
    ):
        raise ValidationError(f"no recording of split {split!r} has truth positions to score against", ds.root)
    return view


def is_validation_name(name: str) -> bool:
    """Whether recording ``name`` is one of the 1 in ``VAL_EVERY`` set aside for validation when a
    dataset has no validation split (a CRC-32 of the name: independent of order and machine)."""
    return zlib.crc32(name.encode()) % VAL_EVERY == 0


def train_val_views(ds: Dataset, train_split: str, val_split: str) -> tuple[Dataset, Dataset, str | None]:
    """The training and validation recordings of ``ds``, and a note saying how validation was chosen
    (None: ``val_split`` as the dataset defines it).

    Where the dataset has no split ``val_split`` but ``train_split`` exists (an imported real
    dataset usually has only ``train``), its other name (``val`` / ``validation``) is used if
    present, else a validation part is derived from the training recordings: those for which
    :func:`is_validation_name` holds (the recording with the smallest CRC-32 if none does). Unknown
    splits are refused naming the splits that exist.
    """
    known = set(ds.manifest["split"].astype(str))
    if val_split not in known and train_split in known and val_split in VALIDATION_SPLITS:
        other = [s for s in VALIDATION_SPLITS if s in known]
        if other:
            return ds.split(train_split), ds.split(other[0]), f"validating on the dataset's {other[0]!r} split"
        train = ds.split(train_split)
        names = train.manifest["name"].astype(str)
        mask = names.map(is_validation_name)
        if not mask.any() and len(train) >= 2:
            mask = names == min(names, key=lambda n: zlib.crc32(n.encode()))
        if len(train) < 2:
            raise ValidationError(
                f"the dataset has no validation split and only {len(train)} {train_split!r} "
                f"recording(s) to set one aside from (splits here: {sorted(known)})",
                ds.root,
            )
        val = train._view(mask.to_numpy())
        return (
            train._view(~mask.to_numpy()),
            val,
            f"no {val_split!r} split in the dataset: validating on {len(val)} of its {len(train)} "
            f"{train_split!r} recordings (1 in {VAL_EVERY} by a CRC-32 of the name: "
            f"{', '.join(val.names[:3])}{', ...' if len(val) > 3 else ''})",
        )
    return ds.split(train_split), ds.split(val_split), None
