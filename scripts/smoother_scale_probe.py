"""How the user protocol's smoother answers to its scale prior (issue 34): one run's paths on a
site's test walks, smoothed on their own fixes with the scale prior's σ (of log scale) at each
value given, beside the run's own calibration; prints the median / p75 error at the surveyed
points, the smoothed paths' length ratio and the scale the smoother found per walk.

    PYTHONPATH=src python scripts/smoother_scale_probe.py RUN DATA [--speed cadence] [--sigmas 0.01,0.05,0.15]

RUN is a suite's run folder (with its ``fuse_calibration_main[_SPEED].json``), DATA the site's
prepared data (the suite's ``data/main``).
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np
import torch

from wearnav import fuse
from wearnav.bench.user_protocol import user_protocol
from wearnav.core.textio import read_json


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", type=Path)
    ap.add_argument("data", type=Path)
    ap.add_argument("--speed", default="model")
    ap.add_argument("--sigmas", default="0.01,0.05,0.15")
    args = ap.parse_args()
    torch.set_num_threads(1)
    cal = read_json(args.run / f"fuse_calibration_main{'' if args.speed == 'model' else '_' + args.speed}.json")
    for sigma in (float(s) for s in args.sigmas.split(",")):
        cfg = dataclasses.replace(fuse.FuseConfig(), scale_prior_log_sigma=sigma)
        out = user_protocol(args.run, args.data, "test", cfg, cal, args.speed)
        e = np.asarray(out["smooth"]["errors"])
        scales = [round(float(v.get("scale", np.nan)), 2) for v in out["smooth"]["traces"].values()]
        print(
            f"scale prior σ {sigma:g}: median {np.median(e):.2f} m, p75 {np.percentile(e, 75):.2f}; "
            f"length ratio {np.mean(out['smooth']['length_ratio']):.2f}; scales per walk {scales}"
        )


if __name__ == "__main__":
    main()
