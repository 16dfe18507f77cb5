"""The fixes' check and the rigid anchorings of :mod:`wearnav.fuse`: one rotation + translation fitted to
the first minute's fixes (``first-fixes``, `track` before issue 25) or to every fix (``rigid``)."""

from __future__ import annotations

import numpy as np

from wearnav.fixcheck import DOWN_WEIGHTED, NO_POSITION, OUTSIDE, REPEAT, UNUSED, USED, WIDE, FixCheck, check_fixes
from wearnav.fuse.config import ANCHOR_S, DOWNWEIGHT, MIN_SPREAD_M, FuseConfig, FuseResult, fix_sigma_m


def rigid_fit(p: np.ndarray, q: np.ndarray, w: np.ndarray) -> tuple[float, np.ndarray, float]:
    """Weighted 2-D Procrustes (rotation + translation, Umeyama 1991) mapping points ``p`` (n, 2)
    onto ``q`` (n, 2) with weights ``w`` (n,): returns yaw (rad), offset (2,) and the weighted RMS
    spread of ``p`` about its centre (m)."""
    pm, qm = np.average(p, axis=0, weights=w), np.average(q, axis=0, weights=w)
    pc, qc = p - pm, q - qm
    cross = np.sum(w * (pc[:, 0] * qc[:, 1] - pc[:, 1] * qc[:, 0]))
    dot = np.sum(w * np.sum(pc * qc, axis=1))
    yaw = float(np.arctan2(cross, dot))
    offset = qm - _rot(yaw) @ pm
    return yaw, offset, float(np.sqrt(np.average(np.sum(pc**2, axis=1), weights=w)))


def _rot(yaw: float) -> np.ndarray:
    return np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])


def _kept(t: np.ndarray, fix_t, fix_pos, fix_accuracy, wide_m: float):
    """The fixes' check (:func:`wearnav.fixcheck.check_fixes`), the indices of the kept ones in
    time order, and their times, positions (M, 2) and accuracies; the record of the counts."""
    check = check_fixes(t[0], t[-1], fix_t, fix_pos, fix_accuracy, wide_m)
    ft = np.asarray(fix_t, np.float64)
    k = np.flatnonzero(check.kept)
    k = k[np.argsort(ft[k], kind="stable")]
    fp = np.asarray(fix_pos, np.float64)[k, :2] if k.size else np.empty((0, 2))
    acc = np.asarray(fix_accuracy, np.float64)
    inside = int(np.sum(check.reason != NO_POSITION) - np.sum(check.reason == OUTSIDE))
    facts = {
        "fixes": inside,
        "fixes_outside_span": int(len(ft) - inside),
        "fixes_nan_accuracy": int(np.sum(~(np.isfinite(acc[k]) & (acc[k] > 0)))),
        "fixes_wide": int(np.sum(check.reason == WIDE)),
        "fixes_repeated": int(np.sum(check.reason == REPEAT)),
    }
    return check, k, ft[k], fp, acc[k], facts


def first_fix_anchor(
    t: np.ndarray, xy: np.ndarray, fix_t, fix_pos, fix_accuracy, cfg: FuseConfig = FuseConfig()
) -> FuseResult:
    """Today's anchoring: a rigid fit over the kept fixes (bad ones dropped first) of the first
    ``ANCHOR_S`` seconds after the first kept fix (more while the path spreads less than
    ``MIN_SPREAD_M`` over them)."""
    return _anchored(t, xy, fix_t, fix_pos, fix_accuracy, ANCHOR_S, cfg)


def rigid_anchor(
    t: np.ndarray, xy: np.ndarray, fix_t, fix_pos, fix_accuracy, cfg: FuseConfig = FuseConfig()
) -> FuseResult:
    """One rotation + translation fitted to every kept fix of the walk, weighted by 1/σ²."""
    return _anchored(t, xy, fix_t, fix_pos, fix_accuracy, None, cfg)


def _anchored(t, xy, fix_t, fix_pos, fix_accuracy, first_s: float | None, cfg: FuseConfig) -> FuseResult:
    t, xy = np.asarray(t, np.float64), np.asarray(xy, np.float64)
    check, k, ft, fp, acc, facts = _kept(t, fix_t, fix_pos, fix_accuracy, cfg.wide_m)
    res = _rigid(t, xy, ft, fp, acc, first_s)
    return _with_fixes(res, check, k, facts)


def _with_fixes(
    res: FuseResult, check: FixCheck, k: np.ndarray, facts: dict, weight: np.ndarray | None = None
) -> FuseResult:
    """``res`` with the per-fix statuses of the kept fixes ``k`` (the first ``fixes_used`` used by
    a rigid fit; by their robust ``weight`` for the smoother) and the counts in its info."""
    if weight is not None:
        down = weight < DOWNWEIGHT
        check.mark(k[~down], USED, weight=weight[~down])
        check.mark(k[down], DOWN_WEIGHTED, f"robust weight below {DOWNWEIGHT:g}", weight[down])
    elif k.size:
        n = res.info.get("fixes_used", len(k))
        check.mark(k[:n], USED, weight=1.0)
        if n < len(k):
            check.mark(k[n:], UNUSED, f"after the first {res.info['span_s']:.0f} s of good fixes")
    res.info.update({**facts, **check.info()})
    if res.method == "none" and (dropped := res.info["fixes_dropped"]):
        res.warnings[0] += f" (every fix dropped: {', '.join(f'{n} {r}' for r, n in dropped.items())})"
    res.warnings[:0] = check.warnings
    res.fixes = check
    return res


def _rigid(t, xy, ft, fp, acc, first_s: float | None) -> FuseResult:
    """The rigid fit over kept fixes (times ``ft`` increasing, ``fp`` (M, 2), ``acc`` (M,))."""
    method = "first-fixes" if first_s is not None else "rigid"
    nan = np.full(len(t), np.nan)
    if ft.size == 0:
        return FuseResult(
            xy.copy(),
            nan,
            "none",
            {"fixes_used": 0},
            ["no location fix inside the walk: the path starts at (0, 0) in the odometry's own frame"],
        )
    w = 1.0 / fix_sigma_m(acc) ** 2
    p = np.stack([np.interp(ft, t, xy[:, k]) for k in range(2)], axis=1)
    n = len(ft) if first_s is None else min(len(ft), max(2, int(np.sum(ft <= ft[0] + first_s))))
    while True:
        yaw, offset, spread = rigid_fit(p[:n], fp[:n], w[:n])
        if spread >= MIN_SPREAD_M or n >= len(ft):
            break
        n += 1
    warn = []
    if len(ft) < 2 or spread < 1e-6:
        yaw = 0.0
        offset = np.average(fp, axis=0, weights=w) - np.average(p, axis=0, weights=w)
        warn.append(
            f"{len(ft)} location fix(es) under a path that does not move: heading unknown, "
            "the path is only shifted onto them"
        )
    out = xy @ _rot(yaw).T + offset
    resid = p[:n] @ _rot(yaw).T + offset - fp[:n]
    rms = float(np.sqrt(np.average(np.sum(resid**2, axis=1), weights=w[:n])))
    return FuseResult(
        out,
        nan,
        method,
        {
            "fixes_used": int(n),
            "heading_offset_deg": float(np.degrees(yaw)),
            "offset_m": [float(v) for v in offset],
            "scale": 1.0,
            "path_spread_m": spread,
            "span_s": float(ft[n - 1] - ft[0]),
            "rms_residual_m": rms,
            # the angular error of a rotation fitted to n points at that spread
            "yaw_std_deg": float(np.degrees(rms / max(spread, 1e-9) / np.sqrt(n))),
        },
        warn,
    )
