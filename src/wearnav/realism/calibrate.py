"""Simulated against real: per-source summaries, the real calibration band of each statistic and
whether the simulated median lies in it.

:func:`compute_realism` runs the whole comparison (simulate, import, segment, compare) and returns
the numbers; :mod:`.report` draws and writes them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from wearnav.realism.fixes import FIX_STATS, fix_stats
from wearnav.realism.gait import MIN_SEGMENT_S, RATE_HZ, SEGMENT_S, TRIM_S
from wearnav.realism.sources import (
    FIX_REAL,
    GROUPS,
    ILC2_CALIBRATION,
    IPIN_CALIBRATION,
    SIM_DURATION_S,
    Group,
    RealSource,
    open_real,
    simulate_realism_walks,
)
from wearnav.realism.stats import STATS, recording_segments, spectrum
from wearnav.recording import Recording

IQR_MIN_SEGMENTS = 8  # fewer real samples than this: the band is ±15 % of the real median
SMALL_SET_TOLERANCE = 0.15


@dataclass
class SourceResult:
    """Every walking segment of one source (simulated or real): statistics rows and |acc| PSDs."""

    label: str
    kind: str  # "sim" | "real"
    how: str  # how walking was picked
    rows: list[dict] = field(default_factory=list)
    psd: list[np.ndarray] = field(default_factory=list)
    recordings: int = 0

    def values(self, stat: str) -> np.ndarray:
        v = np.array([r[stat] for r in self.rows], float)
        return v[np.isfinite(v)]


def summary(v: np.ndarray) -> dict:
    """n, median and quartiles of ``v`` (rounded to 4 decimals); only n where ``v`` is empty."""
    if v.size == 0:
        return {"n": 0}
    q25, q50, q75 = np.percentile(v, [25, 50, 75])
    return {"n": int(v.size), "median": round(float(q50), 4), "q25": round(float(q25), 4), "q75": round(float(q75), 4)}


def weighted_quantiles(samples: list[np.ndarray], q) -> np.ndarray:
    """Quantiles of several samples pooled with equal total weight per sample, so a large real
    set does not outvote a small one (ILC2's many short traces against IPIN's few long ones)."""
    samples = [np.asarray(v, float) for v in samples if np.size(v)]
    x = np.concatenate(samples)
    w = np.concatenate([np.full(v.size, 1.0 / v.size) for v in samples])
    order = np.argsort(x)
    x, w = x[order], w[order]
    cdf = (np.cumsum(w) - 0.5 * w) / w.sum()
    return np.interp(np.asarray(q, float), cdf, x)


def band_of(real: list[np.ndarray]) -> tuple[float, float, str] | None:
    """The calibration band of the real samples of a statistic: their pooled IQR (equal weight
    per source), or ±15 % of their pooled median where they hold few segments."""
    n = sum(np.size(v) for v in real)
    if n == 0:
        return None
    if n >= IQR_MIN_SEGMENTS:
        lo, hi = weighted_quantiles(real, [0.25, 0.75])
        return float(lo), float(hi), "IQR"
    m = float(weighted_quantiles(real, 0.5))
    return m - SMALL_SET_TOLERANCE * abs(m), m + SMALL_SET_TOLERANCE * abs(m), "±15 %"


def compare(sim: SourceResult, real: list[SourceResult]) -> dict:
    """Per statistic: sim median, pooled real median and band, and whether the sim is inside."""
    out = {}
    for stat in STATS:
        s = sim.values(stat)
        r = [x.values(stat) for x in real]
        entry: dict[str, Any] = {
            "sim": summary(s),
            "real": summary(np.concatenate(r) if r else np.empty(0)),
            "per_source": {x.label: summary(x.values(stat)) for x in real},
        }
        band = band_of(r)
        if band is not None and s.size:
            lo, hi, kind = band
            med = float(np.median(s))
            entry.update(band=[round(lo, 4), round(hi, 4)], band_kind=kind, inside=bool(lo <= med <= hi))
        out[stat] = entry
    return out


def compute_realism(
    data: Path,
    work: Path,
    n_sim: int = 12,
    limit: int | None = None,
    seed: int = 0,
    sim_duration_s: float = SIM_DURATION_S,
    groups: tuple[Group, ...] = GROUPS,
    fix_source: RealSource | None = FIX_REAL,
    progress: bool = False,
) -> dict:
    """All the numbers of the report (no files but the imported datasets under ``work``)."""
    data, work = Path(data), Path(work)
    sims: dict[str, list[Recording]] = {}
    real_cache: dict[RealSource, SourceResult] = {}
    freqs = spectrum(np.zeros((int(SEGMENT_S * RATE_HZ), 3)))[0]
    results: dict[str, dict] = {}
    figs: dict[str, list[SourceResult]] = {}

    def collect(label, kind, recs_devices):
        res = SourceResult(label, kind, "")
        hows = set()
        for rec, dev in recs_devices:
            if dev not in rec.devices:
                continue
            rows, psds, how = recording_segments(rec, dev)
            hows.add(how)
            res.rows += rows
            res.psd += psds
            res.recordings += 1
        res.how = "/".join(sorted(hows))
        return res

    for g in groups:
        if g.sim_hold not in sims:
            sims[g.sim_hold] = simulate_realism_walks(g.sim_hold, n_sim, seed, sim_duration_s)
        sim = collect(
            f"sim {g.sim_device}" + (f" {g.sim_hold}" if g.sim_device == "phone" else ""),
            "sim",
            [(r, g.sim_device) for r in sims[g.sim_hold]],
        )
        reals = []
        for src in g.real:
            if src not in real_cache:
                ds, names = open_real(src, data, work, limit)
                real_cache[src] = collect(src.label, "real", ((ds.load(n), src.device) for n in names))
                if progress:
                    print(f"realism: {src.label}: {len(real_cache[src].rows)} segments", flush=True)
            reals.append(real_cache[src])
        figs[g.key] = [sim] + reals
        results[g.key] = {
            "title": g.title,
            "sim": {"label": sim.label, "segments": len(sim.rows), "recordings": sim.recordings},
            "real": [
                {"label": r.label, "segments": len(r.rows), "recordings": r.recordings, "how": r.how} for r in reals
            ],
            "compare": compare(sim, reals),
        }

    # location fixes: IPIN's phone GNSS at its surveyed points vs the simulator's fixes
    fix: dict[str, dict[str, list[float]]] | None = None
    if fix_source is not None:
        ds, names = open_real(fix_source, data, work, limit)
        fix = {"sim fixes": {k: [] for k in FIX_STATS}, fix_source.label: {k: [] for k in FIX_STATS}}
        for rec in next(iter(sims.values())):
            for k, v in fix_stats(rec).items():
                fix["sim fixes"][k] += v
        for n in names:
            for k, v in fix_stats(ds.load(n)).items():
                fix[fix_source.label][k] += v
    return {
        "groups": results,
        "fixes": fix,
        "_figs": figs,
        "_freqs": freqs,
        "settings": {
            "rate_hz": RATE_HZ,
            "segment_s": SEGMENT_S,
            "min_segment_s": MIN_SEGMENT_S,
            "trim_s": TRIM_S,
            "n_sim": n_sim,
            "sim_duration_s": sim_duration_s,
            "limit": limit,
            "seed": seed,
            "ilc2_calibration": ILC2_CALIBRATION,
            "ipin_calibration": IPIN_CALIBRATION,
        },
    }


def fix_compare(fix: dict) -> dict:
    """Per fix statistic: simulated and real summaries, the real IQR and whether the simulated
    median is inside it (same rule as :func:`compare`)."""
    sim, real = fix["sim fixes"], next(v for k, v in fix.items() if k != "sim fixes")
    out = {}
    for k in FIX_STATS:
        s, r = np.asarray(sim.get(k, []), float), np.asarray(real.get(k, []), float)
        e: dict[str, Any] = {"sim": summary(s), "real": summary(r)}
        band = band_of([r])
        if band is not None and s.size:
            e.update(
                band=[round(band[0], 4), round(band[1], 4)],
                band_kind=band[2],
                inside=bool(band[0] <= float(np.median(s)) <= band[1]),
            )
        out[k] = e
    return out
