"""Where the phone (or another device) points against where its walker goes (issue 34's heading frame).

For each dataset: every window (4 s, every 1 s) with a true speed above 0.5 m/s, the direction of
the true displacement in the device's heading frame (:attr:`wearnav.preprocess.PreprocessConfig.heading_frame`,
the horizontal direction of the phone's y − z axis). A phone held in the hand and pointing where
its walker goes gives angles near 0; the share within ±30° and ±60° says how far a heading-frame
model may lean on that; the share within ±30° of the circular mean, how steady a device whose
pointing is offset from the walk (earbuds, a watch: ``--device``) holds that offset. A real
building's recordings use its surveyed points joined by straight
lines as truth, in the frame the data was imported in (``frame_align="none"``); a training mix
(:mod:`wearnav.pretrained.mix`) its own frame (its truth turned into the IMU's); simulated data the
truth's (each device's drawn yaw taken out by ``frame_align="truth"``, a measurement's use of truth).

    PYTHONPATH=src python scripts/heading_offsets.py DATA [DATA ...] [--per-source] [--device earbuds]
"""

from __future__ import annotations

import argparse

import numpy as np

from wearnav.dataset import Dataset
from wearnav.preprocess import SPARSE_TRUTH_HZ, SURVEYED_TRUTH_MAX_GAP_S, PreprocessConfig, align
from wearnav.preprocess.windows import WindowConfig, WindowDataset
from wearnav.pretrained.mix import MIX_FRAME, is_mix

MIN_SPEED = 0.5  # m/s


def angles(data: str, per_source: bool, device: str = "phone") -> dict[str, np.ndarray]:
    ds = Dataset.open(data)
    surveyed = float(np.median(ds.manifest["truth_points"] / ds.manifest["duration"])) < SPARSE_TRUTH_HZ
    simulated = ds.provenance.get("generator") == "wearnav.simulate"
    cfg = PreprocessConfig(
        devices=(device,),
        frame_align=MIX_FRAME if is_mix(data) else "truth" if simulated else "none",
        truth_max_gap=SURVEYED_TRUTH_MAX_GAP_S if surveyed or is_mix(data) else 1.0,
        heading_frame=True,
    )
    out: dict[str, list[np.ndarray]] = {}
    for rec in ds:
        if device not in rec.devices or rec.truth is None:
            continue
        seq = align(rec, cfg)
        w = WindowDataset([seq], WindowConfig(window=100, stride=25))
        if len(w) == 0:
            continue
        v = w[list(range(len(w)))]["vel"].numpy().astype(np.float64)
        fast = np.hypot(v[:, 0], v[:, 1]) > MIN_SPEED
        key = rec.name.split("-")[0] if per_source else str(data)
        out.setdefault(key, []).append(np.degrees(np.arctan2(v[fast, 1], v[fast, 0])))
    return {k: np.concatenate(a) for k, a in out.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data", nargs="+")
    ap.add_argument("--per-source", action="store_true", help="A row per source of a mix (name prefix).")
    ap.add_argument("--device", default="phone", help="The device whose heading frame is measured.")
    args = ap.parse_args()
    print(f"{args.device}:")
    print("| data | windows | circular mean (°) | within ±30° | within ±60° | within ±30° of the mean |")
    print("|---|---|---|---|---|---|")
    for data in args.data:
        for key, a in angles(data, args.per_source, args.device).items():
            mean = float(np.degrees(np.angle(np.mean(np.exp(1j * np.radians(a))))))
            near = np.abs((a - mean + 180) % 360 - 180) < 30
            print(
                f"| {key} | {a.size} | {mean:.1f} | {np.mean(np.abs(a) < 30):.3f} | {np.mean(np.abs(a) < 60):.3f} "
                f"| {np.mean(near):.3f} |"
            )


if __name__ == "__main__":
    main()
