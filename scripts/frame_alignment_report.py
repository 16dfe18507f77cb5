"""Frame-alignment error on a simulated dataset: naive Procrustes vs :mod:`wearnav.preprocess.frames`.

The error of a yaw estimate is measured against the simulator's reported-orientation yaw ψ_d(t)
(drawn offset + yaw walk, reconstructed by re-simulating each walk; see
:func:`wearnav.simulate.walk.reported_yaw_offset`), at every clock sample where the device is
present. Per recording and device this gives the RMS over time (``rms_deg``); the summary takes
median, 90th percentile and maximum of that over recordings, per device and walking mode.

- ``relative``: yaw of device d relative to the reference device (phone) vs ψ_d − ψ_phone.
- ``absolute``: yaw of device d relative to the truth frame (common frame + truth alignment) vs ψ_d.
- ``absolute_vs_drawn``: the same estimate against the fixed drawn offset (meta
  ``quat_yaw_offset_deg``), ignoring the yaw walk, as issue 7's naive figure was measured.

The naive baseline (as in issue 7): one constant yaw per device, the 2-D Procrustes rotation
between its 0.7 Hz low-passed horizontal world acceleration and the truth's acceleration; its
relative yaw is the difference of two such absolute estimates.

    PYTHONPATH=src python scripts/frame_alignment_report.py small [--seed 0] [--out table.md]
"""

from __future__ import annotations

import argparse
import tempfile

import numpy as np
import pandas as pd
from scipy import signal

from wearnav.dataset import Dataset
from wearnav.preprocess import PreprocessConfig, align, frames
from wearnav.simulate import simulate_dataset
from wearnav.simulate.walk import reported_yaw_offset

MODES = ("STW", "PVW", "MVW", "DRW", "DLW")


def _lowpass(z: np.ndarray, rate: float, cutoff: float = 0.7) -> np.ndarray:
    sos = signal.butter(4, cutoff, fs=rate, output="sos")
    return signal.sosfiltfilt(sos, z.real) + 1j * signal.sosfiltfilt(sos, z.imag)


def naive_yaw(z_dev: np.ndarray, z_truth: np.ndarray, w: np.ndarray, rate: float) -> float:
    """Constant yaw (z_dev ≈ e^{iψ} z_truth) by Procrustes on 0.7 Hz low-passed accelerations."""
    return float(np.angle(np.sum(w * _lowpass(z_dev, rate) * np.conj(_lowpass(z_truth, rate)))))


def _err_rows(name, mode, dev, kind, method, est, true, m):
    e = np.rad2deg(np.abs(frames.wrap(est - true)))[m]
    return {
        "recording": name,
        "mode": mode,
        "device": dev,
        "kind": kind,
        "method": method,
        "rms_deg": float(np.sqrt(np.mean(e**2))),
        "max_deg": float(e.max()),
    }


def recording_errors(rec, cfg: frames.FrameConfig = frames.FrameConfig()) -> list[dict]:
    a = align(rec, PreprocessConfig(frame_align="none"))
    rate, mode = a.rate, rec.meta["mode"]
    psi = reported_yaw_offset(rec, a.t)
    rows = []
    cf = frames.common_frame(a.imu, a.mask, a.devices, rate, cfg)
    ref = cf.reference
    common = np.stack([frames.rotate_stacked(a.imu[d], -cf.yaw[d]) for d in range(len(a.devices))])
    tr = frames.truth_yaw(common, a.mask, a.pos, rate, cfg)
    z_truth, ok_truth = frames.truth_acceleration(a.pos, rate)
    z = frames.horizontal(a.imu)
    naive = {}
    for d in range(len(a.devices)):
        if a.mask[d].any():
            naive[d] = naive_yaw(z[d], z_truth, (a.mask[d] & ok_truth).astype(float), rate)
    for d, dev in enumerate(a.devices):
        m = a.mask[d]
        if not m.any():
            continue
        if d != ref:
            true_rel = psi[dev] - psi[a.devices[ref]]
            rows.append(_err_rows(rec.name, mode, dev, "relative", "naive", naive[d] - naive[ref], true_rel, m))
            rows.append(_err_rows(rec.name, mode, dev, "relative", "frames", cf.yaw[d], true_rel, m))
        rows.append(_err_rows(rec.name, mode, dev, "absolute", "naive", np.full(m.size, naive[d]), psi[dev], m))
        rows.append(_err_rows(rec.name, mode, dev, "absolute", "frames", cf.yaw[d] + tr.yaw, psi[dev], m))
        # as issue 7 measured the naive figure: against the fixed drawn offset, ignoring the walk
        drawn = np.full(m.size, np.deg2rad(rec.meta["devices"][dev]["quat_yaw_offset_deg"]))
        rows.append(_err_rows(rec.name, mode, dev, "absolute_vs_drawn", "naive", np.full(m.size, naive[d]), drawn, m))
        rows.append(_err_rows(rec.name, mode, dev, "absolute_vs_drawn", "frames", cf.yaw[d] + tr.yaw, drawn, m))
    return rows


def alignment_report(ds: Dataset, cfg: frames.FrameConfig = frames.FrameConfig()) -> pd.DataFrame:
    """One row per recording, device, kind and method (see module docstring)."""
    rows = []
    for name in ds.manifest["name"]:
        rows += recording_errors(ds.load(name), cfg)
    return pd.DataFrame(rows)


def summary(df: pd.DataFrame) -> pd.DataFrame:
    """Median / p90 / max of the per-recording RMS error, per kind, device, mode and method."""

    def stats(g):
        return pd.Series({"median": g.median(), "p90": g.quantile(0.9), "max": g.max(), "n": g.size})

    parts = []
    for by in (["kind", "device", "mode", "method"], ["kind", "device", "method"]):
        s = df.groupby(by)["rms_deg"].apply(stats).unstack()
        if "mode" not in by:
            s = s.assign(mode="all").set_index("mode", append=True).reorder_levels(["kind", "device", "mode", "method"])
        parts.append(s)
    out = pd.concat(parts).unstack("method")
    out.columns = [f"{m}_{s}" for s, m in out.columns]
    order = [f"{m}_{s}" for m in ("naive", "frames") for s in ("median", "p90", "max")]
    return out[order].round(2)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("preset", nargs="?", default="small")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--data", help="an existing simulated dataset folder instead of simulating")
    ap.add_argument("--out", help="write the summary as Markdown here")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        if args.data:
            ds = Dataset.open(args.data)
        else:
            ds = simulate_dataset(args.preset, tmp, seed=args.seed, progress=False)
        table = summary(alignment_report(ds))
    if args.out:
        from wearnav.core.fileio import write_text_atomic
        from wearnav.core.provenance import provenance

        p = provenance()
        src = f"`{args.data}`" if args.data else f"the `{args.preset}` preset, seed {args.seed}"
        page = [
            f"# Frame alignment error ({args.preset if not args.data else 'given data'})",
            "",
            f"Generated by `scripts/frame_alignment_report.py` ({p['created']}, wearnav {p['wearnav']} "
            f"{p['commit']}) on {src}. Degrees.",
            "",
            __doc__.split("\n\n", 1)[1].split("    PYTHONPATH")[0].strip(),
            "",
            table.reset_index().to_markdown(index=False),
            "",
        ]
        write_text_atomic("\n".join(page), args.out)
    print(table.to_string())


if __name__ == "__main__":
    main()
