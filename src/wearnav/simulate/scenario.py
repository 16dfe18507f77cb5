"""What happens during one walk, as timed events: walking bouts, daily-living episodes, phone
placement changes, deliberate disturbances and device removal (Suite-IN++ Table II).

The scenario is pure bookkeeping (times and kinds); :mod:`.body` and :mod:`.placement` turn it
into motion, and :meth:`Scenario.label_rows` into the recording's interval labels.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from wearnav.simulate.config import HAND_HOLDS, HOLDS_OF_PLACEMENT, REMOVABLE, WalkConfig

WALK_RAMP_S = 1.2  # speeding up from standing (or slowing to a stop) takes about two steps


@dataclass(frozen=True)
class Hold:
    """The phone stays in one placement over [start, end]; between holds it is being moved."""

    placement: str
    start: float
    end: float


@dataclass(frozen=True)
class Episode:
    """A daily-living stop between walking bouts: the body is still from ``start`` to ``end``.

    ``down``/``up`` are the posture transitions for ``sit`` and ``squat`` (None for ``stand``).
    """

    kind: str
    start: float
    end: float
    down: tuple[float, float] | None = None
    up: tuple[float, float] | None = None


@dataclass(frozen=True)
class Disturbance:
    """A deliberate MVW disturbance: ``wrist_shake`` (watch arm), ``head_tilt`` (earbuds) or
    ``phone_shake`` (phone in hand). ``amp`` in rad, ``axis`` 0/1/2 = roll/pitch/yaw for head
    tilts, a unit vector (device frame) for phone shakes."""

    kind: str
    start: float
    end: float
    amp: float
    freq_hz: float = 0.0
    axis: tuple[float, ...] = (1.0, 0.0, 0.0)


@dataclass(frozen=True)
class Removal:
    """DRW: ``device`` comes off at ``start``; with variant ``table`` it is put down by ``end``
    and lies still; with ``stop`` its stream ends at ``start``."""

    device: str
    variant: str
    start: float
    end: float


@dataclass
class Scenario:
    duration: float
    bouts: list[tuple[float, float]]
    episodes: list[Episode] = field(default_factory=list)
    holds: list[Hold] = field(default_factory=list)
    disturbances: list[Disturbance] = field(default_factory=list)
    removal: Removal | None = None

    def label_rows(self, mode: str) -> list[tuple[float, float, str, str]]:
        T = self.duration
        rows: list[tuple[float, float, str, str]] = [(0.0, T, "mode", mode)]
        # placement track: holds and the moves between them
        for i, h in enumerate(self.holds):
            rows.append((h.start, h.end, "placement", h.placement))
            if i + 1 < len(self.holds):
                rows.append((h.end, self.holds[i + 1].start, "placement", "transition"))
        # activity track
        rows.append((0.0, self.bouts[0][0], "activity", "stand"))
        for i, (a, b) in enumerate(self.bouts):
            rows.append((a, b, "activity", "walk"))
            nxt = self.bouts[i + 1][0] if i + 1 < len(self.bouts) else T
            ep = next((e for e in self.episodes if abs(e.start - b) < 1e-9), None)
            if ep is None or ep.kind == "stand":
                rows.append((b, nxt, "activity", "stand"))
                continue
            assert ep.down is not None and ep.up is not None  # a sit or squat episode has both
            (d0, d1), (u0, u1) = ep.down, ep.up
            rows += [
                (b, d0, "activity", "stand"),
                (d0, d1, "activity", f"stand_to_{ep.kind}"),
                (d1, u0, "activity", ep.kind),
                (u0, u1, "activity", f"{ep.kind}_to_stand"),
                (u1, nxt, "activity", "stand"),
            ]
        for d in self.disturbances:
            rows.append((d.start, d.end, "disturbance", d.kind))
        if self.removal is not None:
            rows.append((self.removal.start, T, "removed", self.removal.device))
        return [r for r in rows if r[1] > r[0]]


def _u(rng, lo, hi) -> float:
    return float(rng.uniform(lo, hi))


def _episode(kind: str, t: float, rng, short: bool) -> Episode:
    s = 0.0 if short else 1.0  # short: the smallest plausible durations, to fit a short walk
    if kind == "stand":
        return Episode("stand", t, t + _u(rng, 3, 3 + 5 * s))
    if kind == "sit":
        pre, down, hold, up, post = (
            _u(rng, 0.3, 0.3 + 0.3 * s),
            _u(rng, 1.5, 1.5 + s),
            _u(rng, 4, 4 + 8 * s),
            _u(rng, 1.5, 1.5 + s),
            _u(rng, 0.3, 0.3 + 0.3 * s),
        )
    else:  # squat, e.g. to tie a shoelace
        pre, down, hold, up, post = (
            _u(rng, 0.2, 0.2 + 0.3 * s),
            _u(rng, 0.9, 0.9 + 0.6 * s),
            _u(rng, 3, 3 + 5 * s),
            _u(rng, 0.9, 0.9 + 0.6 * s),
            _u(rng, 0.2, 0.2 + 0.3 * s),
        )
    d0 = t + pre
    u0 = d0 + down + hold
    return Episode(kind, t, u0 + up + post, (d0, d0 + down), (u0, u0 + up))


def _walking(cfg: WalkConfig, rng, t0: float, t1: float):
    if cfg.mode != "DLW":
        return [(t0, t1)], []
    min_bout = 7.0
    kinds = list(rng.permutation(["stand", "sit", "squat"]))
    bouts: list[tuple[float, float]] = []
    episodes: list[Episode] = []
    t = t0
    while True:
        bout = _u(rng, 8.0, max(9.0, min(25.0, cfg.duration_s / 4)))
        ep = _episode(kinds[len(episodes) % 3], t + bout, rng, short=False)
        if ep.end + min_bout > t1 and not episodes:  # make sure one episode fits
            bout = min_bout
            ep = _episode(kinds[0], t + bout, rng, short=True)
        if ep.end + min_bout > t1:
            bouts.append((t, t1))
            return bouts, episodes
        bouts.append((t, t + bout))
        episodes.append(ep)
        t = ep.end


def _phone_holds(cfg: WalkConfig, rng) -> list[Hold]:
    T = cfg.duration_s
    if cfg.placement != "MP":
        hold = cfg.phone_hold
        if hold is None:
            options = HOLDS_OF_PLACEMENT[cfg.placement]
            # Handheld is mostly texting-style; swinging in the hand is the less common variant.
            probs = [0.7, 0.3] if options == ("texting", "swinging") else None
            hold = str(rng.choice(options, p=probs))
        return [Hold(hold, 0.0, T)]
    holds = []
    t, p = 0.0, str(rng.choice(HAND_HOLDS))
    while True:
        dur = float(np.clip(_u(rng, 0.12, 0.3) * T, 6.0, 45.0))
        pocket = lambda q: q.endswith("pocket")
        nxt = str(rng.choice([q for q in HOLDS_OF_PLACEMENT["MP"] if q != p]))
        move = _u(rng, 1.6, 2.4) if pocket(p) or pocket(nxt) else _u(rng, 1.0, 1.6)
        if t + dur + move + 6.0 > T:
            holds.append(Hold(p, t, T))
            return holds
        holds.append(Hold(p, t, t + dur))
        t, p = t + dur + move, nxt


def _disturbances(cfg: WalkConfig, holds: list[Hold], rng) -> list[Disturbance]:
    if cfg.mode != "MVW":
        return []
    T = cfg.duration_s
    out: list[Disturbance] = []
    order = [str(k) for k in rng.permutation(["wrist_shake", "head_tilt", "phone_shake"])]
    t = _u(rng, 2.5, 5.0)
    i = 0
    while True:
        dur = _u(rng, 1.5, 3.0)
        if t + dur > T - 2.0:
            return out
        kind = order[i % 3]
        i += 1
        if kind == "phone_shake" and not any(
            h.placement in HAND_HOLDS and h.start <= t and t + dur <= h.end for h in holds
        ):
            kind = order[i % 3]
            i += 1
            if kind == "phone_shake":
                kind = "head_tilt"
        if kind == "wrist_shake" and "watch" not in cfg.devices:
            kind = "head_tilt"
        if kind == "wrist_shake":  # forearm pronation/supination, vigorous
            d = Disturbance(kind, t, t + dur, np.deg2rad(_u(rng, 20, 35)), _u(rng, 2.5, 4.0))
        elif kind == "head_tilt":  # tilt, nod or turn of the head, and back
            axis = int(rng.integers(0, 3))
            amp = np.deg2rad(_u(rng, 15, 35)) * float(rng.choice([-1, 1]))
            d = Disturbance(kind, t, t + dur, amp, 0.0, (float(axis),))
        else:
            ax = rng.standard_normal(3)
            d = Disturbance(
                kind,
                t,
                t + dur,
                np.deg2rad(_u(rng, 8, 20)),
                _u(rng, 2.0, 4.0),
                tuple(float(a) for a in ax / np.linalg.norm(ax)),
            )
        out.append(d)
        t += dur + _u(rng, 3.0, 9.0)


def _removal(cfg: WalkConfig, rng) -> Removal | None:
    if cfg.mode != "DRW":
        return None
    if cfg.removal is not None:
        dev, _, variant = cfg.removal.partition(":")
    else:
        dev = str(rng.choice([d for d in REMOVABLE if d in cfg.devices]))
        # AirPods stop streaming motion once out of the ear; a watch keeps streaming when put down.
        p_table = 0.7 if dev == "watch" else 0.3
        variant = "table" if rng.uniform() < p_table else "stop"
    t = _u(rng, 0.35, 0.6) * cfg.duration_s
    end = t + _u(rng, 1.5, 2.5) if variant == "table" else t
    return Removal(dev, variant, t, end)


def make_scenario(cfg: WalkConfig, rng: np.random.Generator) -> Scenario:
    T = cfg.duration_s
    t0 = _u(rng, 1.5, 3.0)
    t1 = T - _u(rng, 1.0, 2.0)
    bouts, episodes = _walking(cfg, rng, t0, t1)
    holds = _phone_holds(cfg, rng)
    return Scenario(
        duration=T,
        bouts=bouts,
        episodes=episodes,
        holds=holds,
        disturbances=_disturbances(cfg, holds, rng),
        removal=_removal(cfg, rng),
    )
