"""Location fixes against surveyed reference points: error, reported accuracy, outages, jumps.

:func:`fix_stats` compares a recording's fixes with the points a surveyor marked (IPIN's POSI
points; in the simulator, its truth every :data:`SIM_REFERENCE_EVERY_S`).
"""

from __future__ import annotations

import numpy as np

from wearnav.metrics import FIX_MAX_GAP_S, errors_at_reference
from wearnav.recording import Recording

OUTAGE_GAP_S = 2.5
JUMP_SPEED_MPS = 4.0
SIM_REFERENCE_EVERY_S = 10.0
FIX_STATS = ("error_m", "acc_over_error", "fix_speed", "outage_s", "outage_share", "jumps_per_100")


def fix_stats(rec: Recording) -> dict[str, list[float]]:
    """Fix error at the reference points, accuracy/error there, outage lengths and jump rate."""
    fx = rec.fixes
    out: dict[str, list[float]] = {k: [] for k in FIX_STATS}
    if fx is None or len(fx.t) < 2 or rec.truth is None:
        return out
    if rec.meta.get("source") == "simulator":
        t_ref = np.arange(SIM_REFERENCE_EVERY_S, rec.truth.t[-1], SIM_REFERENCE_EVERY_S)
        p_ref = np.stack([np.interp(t_ref, rec.truth.t, rec.truth.pos[:, k]) for k in range(2)], 1)
    else:
        t_ref, p_ref = rec.truth.t, rec.truth.pos[:, :2]
    fpos = np.asarray(fx.pos, float)[:, :2]
    ok = np.isfinite(fpos).all(1)
    t_f, p_f = fx.t[ok], fpos[ok]
    err = errors_at_reference(t_f, p_f, t_ref, p_ref, FIX_MAX_GAP_S)
    out["error_m"] = err.tolist()
    if fx.accuracy is not None and err.size:
        i = np.searchsorted(t_f, t_ref)
        keep = []
        for k, t in enumerate(t_ref):
            j = [q for q in (i[k] - 1, i[k]) if 0 <= q < t_f.size]
            if j and min(abs(t_f[q] - t) for q in j) <= FIX_MAX_GAP_S:
                keep.append(min(j, key=lambda q: abs(t_f[q] - t)))
        accu = np.asarray(fx.accuracy, float)[ok][keep]
        good = np.isfinite(accu) & (err > 0)
        out["acc_over_error"] = (accu[good] / err[good]).tolist()
    dt = np.diff(t_f)
    out["outage_s"] = dt[dt > OUTAGE_GAP_S].tolist()
    span = t_f[-1] - t_f[0]
    out["outage_share"] = [float(dt[dt > OUTAGE_GAP_S].sum() / span) if span > 0 else 0.0]
    step = np.linalg.norm(np.diff(p_f, axis=0), axis=1)
    out["fix_speed"] = (step / np.maximum(dt, 1e-3)).tolist()
    out["jumps_per_100"] = [float(100.0 * np.mean(step > JUMP_SPEED_MPS * np.maximum(dt, 1.0)))]
    return out
