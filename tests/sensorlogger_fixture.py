"""Damage a Sensor Logger export the way real ones differ (issue 8). The export itself is written by
the package (:mod:`wearnav.importers.sensorlogger_export`, what ``wearnav simulate --format
sensorlogger`` uses)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pymap3d
from scipy.spatial.transform import Rotation

__all__ = ["edit_csv", "glitch_quaternion", "prepend_stale_fix", "cut_gap", "resample_rows"]


# ---- exports as they really are (issue 8): damage an export the way real ones differ -----------


def edit_csv(path: str | Path, fn) -> None:
    path = Path(path)
    fn(pd.read_csv(path)).to_csv(path, index=False)


def glitch_quaternion(path: str | Path, row: int, angle: float = 1.0) -> None:
    """One quaternion turned by ``angle`` rad about the device's x axis, its neighbours untouched
    (a start-up glitch). Works on Orientation.csv (qw..) and WristMotion / Headphone (quaternionW..)."""

    def fn(df):
        cols = ["qw", "qx", "qy", "qz"] if "qw" in df else [f"quaternion{a}" for a in "WXYZ"]
        q = df.loc[row, cols].to_numpy(float)
        r = Rotation.from_quat(q[[1, 2, 3, 0]]) * Rotation.from_rotvec([angle, 0.0, 0.0])
        df.loc[row, cols] = r.as_quat()[[3, 0, 1, 2]]
        return df

    edit_csv(path, fn)


def prepend_stale_fix(
    path: str | Path, seconds_before: float = 90.0, km_away: float = 5.0, accuracy: float = 3000.0
) -> None:
    """A cached fix from before the recording as the first row of Location.csv: negative
    ``seconds_elapsed``, ``km_away`` north, ``accuracy`` metres."""

    def fn(df):
        row = df.iloc[[0]].copy()
        row["time"] = int(df["time"].iloc[0]) - int(seconds_before * 1e9)
        row["seconds_elapsed"] = float(df["seconds_elapsed"].iloc[0]) - seconds_before
        row["latitude"] = pymap3d.enu2geodetic(
            0.0, km_away * 1e3, 0.0, df["latitude"].iloc[0], df["longitude"].iloc[0], 0.0
        )[0]
        row["horizontalAccuracy"] = accuracy
        return pd.concat([row, df], ignore_index=True)

    edit_csv(path, fn)


def cut_gap(path: str | Path, start_s: float, length_s: float) -> None:
    """Remove the rows of ``length_s`` seconds starting ``start_s`` after the file's first row."""

    def fn(df):
        t = (df["time"] - df["time"].iloc[0]) / 1e9
        return df[(t < start_s) | (t >= start_s + length_s)]

    edit_csv(path, fn)


def resample_rows(path: str | Path, rate_hz: float) -> None:
    """Keep the rows nearest to a ``rate_hz`` clock (a slower stream of the same phone)."""

    def fn(df):
        t = (df["time"].to_numpy() - df["time"].iloc[0]) / 1e9
        want = np.arange(0.0, t[-1], 1.0 / rate_hz)
        return df.iloc[np.unique(np.clip(np.searchsorted(t, want), 0, len(df) - 1))]

    edit_csv(path, fn)
