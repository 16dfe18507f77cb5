"""Dataset folders: ``*.h5`` recordings plus ``manifest.csv`` (one row per recording).

Write with :class:`DatasetWriter` (the simulator and every importer do), read with
:meth:`Dataset.open`. A Dataset is an immutable view of a manifest: :meth:`Dataset.filter` and
:meth:`Dataset.split` return narrower views of the same folder.

The manifest columns are ``name, file, duration, devices, mode, subject, placement, scene,
source, split, noise_level, truth_points, fixes``, taken from each recording's meta;
``devices`` is a ``;``-joined list of device names and ``noise_level`` the location-fix noise
level of simulated data (EasyTrack's L1/L2/L3).
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

import pandas as pd
import yaml

from wearnav.errors import FormatError, MissingFileError, ValidationError
from wearnav.provenance import provenance
from wearnav.recording import Recording

MANIFEST = "manifest.csv"
PROVENANCE = "dataset.yaml"
MANIFEST_COLUMNS = [
    "name", "file", "duration", "devices", "mode", "subject", "placement", "scene", "source",
    "split", "noise_level", "truth_points", "fixes",
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


class DatasetWriter:
    """Writes recordings into a new dataset folder, all or nothing.

    Recordings go to a hidden sibling folder; :meth:`close` writes the manifest and
    ``dataset.yaml`` (what made the dataset: ``provenance`` given by the caller, e.g. the
    simulator preset and seed or the importer and source, plus package version, commit and time)
    and renames that folder to ``root`` (replacing an earlier dataset there). An exception inside the ``with``
    block removes the partial folder, so a failed import or simulation leaves nothing behind.

    >>> with DatasetWriter("out") as w:
    ...     w.add(rec, split="train")
    """

    def __init__(self, root: str | Path, provenance: dict | None = None):
        self.root = Path(root)
        self.provenance = dict(provenance or {})
        if self.root.exists() and not (
            self.root.is_dir() and ((self.root / MANIFEST).exists() or not any(self.root.iterdir()))
        ):
            raise ValidationError("exists and is not a wearnav dataset folder; not overwriting it", self.root)
        self.root.parent.mkdir(parents=True, exist_ok=True)
        self.tmp = Path(tempfile.mkdtemp(prefix=f".{self.root.name}.", suffix=".partial", dir=self.root.parent))
        self.rows: list[dict] = []

    def add(self, rec: Recording, split: str = "") -> None:
        if any(r["name"] == rec.name for r in self.rows):
            raise ValidationError(f"duplicate recording name {rec.name!r}", self.root)
        file = f"{rec.name}.h5"
        rec.save(self.tmp / file)
        self.rows.append(manifest_row(rec, file, split))

    def close(self) -> Path:
        """Write the manifest and move the finished dataset into place; returns ``root``."""
        df = pd.DataFrame(self.rows)
        for col in MANIFEST_COLUMNS:
            if col not in df.columns:
                df[col] = pd.Series(dtype=object)
        df[MANIFEST_COLUMNS].to_csv(self.tmp / MANIFEST, index=False)
        info = {**self.provenance, **provenance(), "recordings": len(self.rows)}
        (self.tmp / PROVENANCE).write_text(yaml.safe_dump(info, sort_keys=False), encoding="utf-8")
        if self.root.exists():
            shutil.rmtree(self.root)
        os.replace(self.tmp, self.root)
        return self.root

    def abort(self) -> None:
        shutil.rmtree(self.tmp, ignore_errors=True)

    def __enter__(self) -> "DatasetWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


class Dataset:
    """A view of a dataset folder: ``manifest`` (DataFrame), ``load(name)``, filters and splits."""

    def __init__(self, root: Path, manifest: pd.DataFrame):
        self.root = root
        self.manifest = manifest.reset_index(drop=True)

    @classmethod
    def open(cls, root: str | Path) -> "Dataset":
        root = Path(root)
        if not root.is_dir():
            raise MissingFileError("no such dataset folder", root)
        path = root / MANIFEST
        if not path.exists():
            raise FormatError(f"not a wearnav dataset (no {MANIFEST})", root)
        try:
            df = pd.read_csv(path, dtype={c: str for c in ("subject", "split", "mode", "placement",
                                                          "scene", "source", "noise_level")})
        except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
            raise FormatError(f"unreadable manifest ({exc})", path) from None
        missing = [c for c in ("name", "file", "duration", "devices") if c not in df.columns]
        if missing:
            raise FormatError(f"manifest lacks columns {missing}", path)
        for col in MANIFEST_COLUMNS:
            if col not in df.columns:
                df[col] = ""
        str_cols = ["devices", "mode", "subject", "placement", "scene", "source", "split", "noise_level"]
        df[str_cols] = df[str_cols].fillna("").astype(str)
        return cls(root, df)

    @property
    def provenance(self) -> dict:
        """Contents of ``dataset.yaml`` (empty for folders written before it existed)."""
        path = self.root / PROVENANCE
        if not path.exists():
            return {}
        try:
            return yaml.safe_load(path.read_text(encoding="utf-8")) or {}
        except yaml.YAMLError as exc:
            raise FormatError(f"unreadable ({exc})", path) from None

    # ---- views --------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.manifest)

    @property
    def names(self) -> list[str]:
        return self.manifest["name"].tolist()

    def _view(self, mask) -> "Dataset":
        return Dataset(self.root, self.manifest[mask])

    def filter(self, mode=None, subject=None, placement=None, devices=None, source=None,
               noise_level=None) -> "Dataset":
        """Keep recordings matching every given criterion.

        Each of ``mode``, ``subject``, ``placement``, ``source``, ``noise_level`` is a value or a
        list of values;
        ``devices`` is a list of device names that must all be present.
        """
        m = self.manifest
        mask = pd.Series(True, index=m.index)
        for col, want in (("mode", mode), ("subject", subject), ("placement", placement),
                          ("source", source), ("noise_level", noise_level)):
            if want is not None:
                want = [want] if isinstance(want, str | int) else list(want)
                mask &= m[col].isin([str(w) for w in want])
        if devices is not None:
            need = set([devices] if isinstance(devices, str) else devices)
            mask &= m["devices"].map(lambda s: need <= set(s.split(";")))
        return self._view(mask)

    def split(self, *names: str) -> "Dataset":
        """Recordings whose ``split`` is one of ``names`` (e.g. ``split("test", "test_unseen")``)."""
        known = set(self.manifest["split"])
        unknown = [n for n in names if n not in known]
        if unknown:
            raise ValidationError(f"unknown split {unknown}; this dataset has {sorted(known)}", self.root)
        return self._view(self.manifest["split"].isin(names))

    # ---- loading ------------------------------------------------------------------------
    def path(self, name: str) -> Path:
        rows = self.manifest[self.manifest["name"] == name]
        if rows.empty:
            raise ValidationError(f"no recording named {name!r}", self.root)
        return self.root / rows["file"].iloc[0]

    def load(self, name: str) -> Recording:
        return Recording.load(self.path(name))

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


def write_dataset(root: str | Path, recordings: Iterable[tuple[Recording, str]],
                  provenance: dict | None = None) -> Dataset:
    """Write (recording, split) pairs to ``root`` and open the result."""
    with DatasetWriter(root, provenance) as w:
        for rec, split in recordings:
            w.add(rec, split)
    return Dataset.open(root)
