"""Small, valid inputs for every importer and the malformations the robustness suite applies.

Each seed is a dict {relative path: text} in the format's original layout, cut from the real files
in shared/data (decompressed, a few hundred rows) or, for Sensor Logger, written by
``wearnav.importers.sensorlogger_export.write_export``. Seeds live in memory; every example writes its own copy
into a fresh temporary folder, never into the repository.
"""

from __future__ import annotations

import gzip
import lzma
import re
from dataclasses import dataclass
from pathlib import Path

# (format, the file a mutation targets, its field separator or None for whitespace)
TARGETS = {
    "ilc2": ("site1/F4/path_data_files/trace.txt", "\t"),
    "ipin2023": ("logs/IPIN2023_T3_TrainingTrial01_repetition01.txt", ";"),
    "motionsense": ("A_DeviceMotion_data/wlk_7/sub_1.csv", ","),
    "uci-hapt": ("RawData/acc_exp01_user01.txt", None),
    "uji-phone-watch": ("DATA/s01/s01_01_sp.csv", ","),
    "oxford-steps": ("validation/user1_armband_1506423438471.csv", ","),
    "sensorlogger": ("export/TotalAcceleration.csv", ","),
}
# Other files a mutation may hit instead (labels, subject tables, metadata).
SIDE_FILES = {
    "ilc2": ["site1/F4/floor_info.json"],
    "uci-hapt": ["RawData/labels.txt", "RawData/gyro_exp01_user01.txt", "activity_labels.txt"],
    "motionsense": ["data_subjects_info.csv"],
    "uji-phone-watch": ["DATA/s01/s01_01_sw.csv", "DATA/subjects_info.csv", "DATA/executions_info.csv"],
    "sensorlogger": [
        "export/Metadata.csv",
        "export/Gyroscope.csv",
        "export/Orientation.csv",
        "export/Location.csv",
        "export/WristMotion.csv",
    ],
}
FORMATS = list(TARGETS)
# A dataset folder's manifest is malformed the same way (the "format" of ``wearnav info``).
TARGETS["dataset"] = ("d/manifest.csv", ",")
SIDE_FILES["dataset"] = ["d/dataset.yaml"]
REAL_FORMATS = [f for f in FORMATS if f != "sensorlogger"]


def _text(path: Path) -> str:
    raw = path.read_bytes()
    if path.suffix == ".xz":
        raw = lzma.decompress(raw)
    elif path.suffix == ".gz":
        raw = gzip.decompress(raw)
    return raw.decode("utf-8")


ILC2_TYPES = ("TYPE_ACCELEROMETER", "TYPE_GYROSCOPE", "TYPE_ROTATION_VECTOR", "TYPE_WAYPOINT")


def _head(path: Path, n: int) -> str:
    return "".join(_text(path).splitlines(keepends=True)[:n])


def build_seed(fmt: str, data: Path | None) -> dict[str, str]:
    """The seed files of ``fmt`` (``data`` is shared/data; unused for sensorlogger)."""
    if fmt == "sensorlogger":
        import tempfile

        from synthetic import synthetic_recording
        from wearnav.importers.sensorlogger_export import write_export

        with tempfile.TemporaryDirectory() as tmp:
            folder = write_export(
                synthetic_recording(duration=8.0, seed=1),
                Path(tmp) / "export",
                platform="android",
                total_acceleration=True,
            )
            return {f"export/{p.name}": p.read_text(encoding="utf-8") for p in sorted(folder.iterdir())}
    assert data is not None
    if fmt == "ilc2":
        trace = sorted((data / "ilc2_indoor_location/site1/F4/path_data_files").glob("*.txt.gz"))[0]
        lines = _text(trace).splitlines()
        # The rows the importer reads, by type, over the trace's first 4 s (a line count would take
        # whatever else the trace holds there, e.g. Wi-Fi scans), between the header and the footer.
        rows = [ln for ln in lines if ln.startswith("#") and "endTime" not in ln]
        t0 = min(int(ln.split("\t")[0]) for ln in lines if ln.split("\t")[1:2] == ["TYPE_ACCELEROMETER"])
        rows += [
            ln
            for ln in lines
            if ln.split("\t")[1:2] and ln.split("\t")[1] in ILC2_TYPES and 0 <= int(ln.split("\t")[0]) - t0 <= 4000
        ]
        rows.append(lines[-1])  # the endTime footer
        return {
            TARGETS[fmt][0]: "\n".join(rows) + "\n",
            "site1/F4/floor_info.json": _text(trace.parent.parent / "floor_info.json"),
        }
    if fmt == "ipin2023":
        log = next((data / "ipin2023_track3").rglob("IPIN2023_T3_TrainingTrial01_repetition01.txt.xz"))
        keep = []
        for ln in _text(log).splitlines():
            if ln.startswith("%"):
                keep.append(ln)
            elif ln[:4] in ("ACCE", "GYRO", "AHRS", "GNSS", "POSI", "PRES", "BLE4"):
                app_t = float(ln.split(";")[1])
                if 60.0 <= app_t <= 69.0:
                    keep.append(ln)
        return {TARGETS[fmt][0]: "\n".join(keep) + "\n"}
    if fmt == "motionsense":
        root = data / "motionsense"
        return {
            TARGETS[fmt][0]: _head(root / "A_DeviceMotion_data/wlk_7/sub_1.csv.xz", 201),
            "data_subjects_info.csv": _text(root / "data_subjects_info.csv"),
        }
    if fmt == "uci-hapt":
        root = data / "uci_hapt"
        labels = [
            ln
            for ln in _text(root / "RawData/labels.txt.xz").splitlines()
            if ln.split()[:2] == ["1", "1"] and int(ln.split()[4]) <= 1400
        ]
        return {
            TARGETS[fmt][0]: _head(root / "RawData/acc_exp01_user01.txt.xz", 1400),
            "RawData/gyro_exp01_user01.txt": _head(root / "RawData/gyro_exp01_user01.txt.xz", 1400),
            "RawData/labels.txt": "\n".join(labels) + "\n",
            "activity_labels.txt": _text(root / "activity_labels.txt"),
        }
    if fmt == "uji-phone-watch":
        root = data / "uji_phone_watch_har/DATA"
        return {
            TARGETS[fmt][0]: _head(root / "s01/s01_01_sp.csv.xz", 301),
            "DATA/s01/s01_01_sw.csv": _head(root / "s01/s01_01_sw.csv.xz", 301),
            # s01 recorded one execution in this slice (the table declares how many exist).
            "DATA/subjects_info.csv": re.sub(r"(?m)^(s01,.*,)\d+$", r"\g<1>1", _text(_one(root, "subjects_info.csv"))),
            "DATA/executions_info.csv": _text(_one(root, "executions_info.csv")),
        }
    if fmt == "oxford-steps":
        src = data / "oxford_step_counter/validation/user1_armband_1506423438471.csv.xz"
        return {TARGETS[fmt][0]: _head(src, 600)}
    raise KeyError(fmt)


def _one(folder: Path, name: str) -> Path:
    for cand in (folder / name, folder / (name + ".xz"), folder / (name + ".gz")):
        if cand.exists():
            return cand
    raise FileNotFoundError(folder / name)


def materialise(seed: dict[str, str], root: Path) -> None:
    for rel, text in seed.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text, encoding="utf-8")


# ---- malformations -----------------------------------------------------------------------------

BAD_VALUES = ["1e30", "-1e30", "nan", "inf", "", "abc", "0", "-0.5", "1e-30", "999999999999999999999"]
KINDS = [
    "truncate",
    "truncate_gz",
    "rename",
    "corrupt_cell",
    "corrupt_5pct",
    "duplicate_row",
    "duplicate_all",
    "reverse",
    "swap_rows",
    "drop_file",
    "empty_file",
    "crlf",
]


@dataclass(frozen=True)
class Mutation:
    kind: str
    side: float  # < 0.7 targets the main file, else a side file (where the format has any)
    where: float  # position in [0, 1): byte, row or field, by kind
    column: float  # field position in [0, 1)
    value: str  # replacement text for corruptions and renames

    def describe(self) -> str:
        return f"{self.kind}(side={self.side:.2f}, where={self.where:.3f}, col={self.column:.2f}, value={self.value!r})"


def _split(line: str, sep: str | None) -> list[str]:
    return line.split(sep) if sep else line.split()


def _join(fields: list[str], sep: str | None) -> str:
    return (sep or " ").join(fields)


def apply(mutation: Mutation, fmt: str, root: Path) -> Path:
    """Apply ``mutation`` to the seed written under ``root``; returns the file it changed."""
    main, sep = TARGETS[fmt]
    sides = SIDE_FILES.get(fmt, [])
    if mutation.side >= 0.7 and sides:
        rel = sides[int((mutation.side - 0.7) / 0.3 * len(sides)) % len(sides)]
    else:
        rel = main
    path = root / rel
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines()
    k = mutation.kind
    data_idx = [i for i, ln in enumerate(lines) if ln and ln[0] not in "#%"]
    if rel.endswith(".csv") and data_idx and data_idx[0] == 0:
        data_idx = data_idx[1:]  # the header line

    def pick(frac: float, among: list[int]) -> int:
        return among[min(int(frac * len(among)), len(among) - 1)]

    if k == "truncate":
        cut = int(mutation.where * len(text.encode("utf-8")))
        path.write_bytes(text.encode("utf-8")[:cut])
    elif k == "truncate_gz":
        raw = gzip.compress(text.encode("utf-8"))
        path.unlink()
        path = path.with_name(path.name + ".gz")
        path.write_bytes(raw[: max(1, int(mutation.where * len(raw)))])
    elif k == "drop_file":
        path.unlink()
    elif k == "empty_file":
        path.write_text("")
    elif k == "crlf":
        path.write_bytes(text.replace("\n", "\r\n").encode("utf-8"))
    elif not data_idx:
        path.write_text("")
    else:
        if k == "rename":  # a header field, or the type tag of a tagged row
            i = 0 if rel.endswith(".csv") else pick(mutation.where, data_idx)
            fields = _split(lines[i], sep) or [""]
            if rel.endswith(".csv"):
                j = min(int(mutation.column * len(fields)), len(fields) - 1)
            else:
                j = {"ilc2": 1, "ipin2023": 0}.get(fmt, int(mutation.column * len(fields)))
            j = min(j, len(fields) - 1)
            fields[j] = mutation.value or fields[j].upper() + "_X"
            lines[i] = _join(fields, sep)
        elif k in ("corrupt_cell", "corrupt_5pct"):
            rows = (
                [pick(mutation.where, data_idx)]
                if k == "corrupt_cell"
                else data_idx[int(mutation.where * 20) % 20 :: 20]
            )
            for i in rows:
                fields = _split(lines[i], sep) or [""]
                lo = min(2 if fmt == "ilc2" else 1 if fmt == "ipin2023" else 0, len(fields) - 1)
                j = lo + min(int(mutation.column * (len(fields) - lo)), len(fields) - lo - 1)
                fields[j] = mutation.value
                lines[i] = _join(fields, sep)
        elif k == "duplicate_row":
            i = pick(mutation.where, data_idx)
            lines.insert(i + 1, lines[i])
        elif k == "duplicate_all":
            order = []
            for i, ln in enumerate(lines):
                order.append(ln)
                if i in set(data_idx):
                    order.append(ln)
            lines = order
        elif k == "reverse":
            rev = [lines[i] for i in data_idx][::-1]
            for i, ln in zip(data_idx, rev):
                lines[i] = ln
        elif k == "swap_rows":
            a, b = pick(mutation.where, data_idx), pick(mutation.column, data_idx)
            lines[a], lines[b] = lines[b], lines[a]
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def source_arg(fmt: str, root: Path) -> Path:
    """What the user passes as SRC for a seed written under ``root``."""
    return root / "export" if fmt == "sensorlogger" else root
