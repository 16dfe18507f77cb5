"""Issue 35 "done when": the share of "walking" the shipped activity model gives simulated Sensor
Logger walks, through `classify` (every window of the export) and through the live tracker (the label
the page shows after each update, the export replayed message by message as Sensor Logger pushes it).

The simulator is one of the model's training sources, so this is a check of the path from an export to
a label, not an independent measurement.

    PYTHONPATH=src python scripts/activity_sensorlogger.py --walks 5 --seconds 180
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav import pretrained
from wearnav.importers import sensorlogger
from wearnav.importers.sensorlogger_export import simulated_export
from wearnav.live.buffer import SessionBuffer
from wearnav.live.replay import build
from wearnav.live.tracker import LiveTracker
from wearnav.train.labelling import label_recordings


def live_labels(folder: Path) -> list[str]:
    """The activity label the live page shows, each time the tracker refreshes it."""
    rp = build(folder, batch_s=0.2, start_ns=time.time_ns())
    buf = SessionBuffer(rp.session_id, rp.platform, rp.standardised)
    tracker = LiveTracker(step_s=2.0)
    labels, last = [], None
    for msg in rp.messages:
        buf.add(msg["payload"])
        tracker.update(buf)
        a = tracker.activity
        if a is not None and a.get("t_s") != last:
            labels.append(a["label"])
            last = a.get("t_s")
    return labels


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--walks", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=180.0)
    args = ap.parse_args()
    model = pretrained.SHIPPED[pretrained.ACTIVITY].path
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(1, args.walks + 1):
            folder = Path(tmp) / f"export{seed}"
            simulated_export(folder, seed=seed, duration_s=args.seconds)
            recs = list(sensorlogger.read(folder))
            res = label_recordings(recs, model, Path(tmp) / f"out{seed}")
            df = pd.read_csv(res["files"][0])
            offline = df.loc[df["label"] == "walking", "windows"].sum() / df["windows"].sum()
            live = live_labels(folder)
            rows.append(
                {
                    "seed": seed,
                    "classify windows": int(df["windows"].sum()),
                    "classify walking": round(float(offline), 3),
                    "live labels": len(live),
                    "live walking": round(float(np.mean([x == "walking" for x in live])), 3) if live else None,
                    "other labels": ", ".join(sorted(set(df["label"]) - {"walking"})),
                }
            )
            print(rows[-1], flush=True)
    table = pd.DataFrame(rows)
    print(table.to_markdown(index=False))
    w = table["classify windows"]
    print(
        f"pooled: classify {np.sum(table['classify walking'] * w) / w.sum():.3f} of {w.sum()} windows walking; "
        f"live {np.sum(table['live walking'] * table['live labels']) / table['live labels'].sum():.3f} "
        f"of {table['live labels'].sum()} labels walking"
    )


if __name__ == "__main__":
    main()
