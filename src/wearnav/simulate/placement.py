"""Where each device is on the body: its pose (position, orientation world←device) over time.

- earbuds: in the right ear, on the head;
- watch: on the left wrist, on the swinging forearm;
- phone: in one of six placements (texting, swinging in the hand, at the ear for a call, with the
  hand drawn per recording: right 65 %, left 35 %; right front trouser pocket on the thigh, right
  back pocket, bag), changing
  between them with smooth hand motions of one to two seconds (PVW/MVW);
- a removed device (DRW) is either put down on a table, where it lies still, or stops streaming.

Every device has a random fixed mounting rotation relative to its segment (how the phone sits in
the pocket, how the watch sits on the wrist ...). Device frames follow the phone convention:
x to the right of the screen, y to the top, z out of the screen.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.signal import cont2discrete, lfilter

from wearnav.simulate.body import Body, BodyState
from wearnav.simulate.geometry import (
    apply,
    blend_rotations,
    exp_so3,
    from_axes,
    log_so3,
    random_rotation,
    rot_x,
    rot_y,
    rot_z,
)
from wearnav.simulate.path import GRID_HZ
from wearnav.simulate.scenario import Removal, Scenario
from wearnav.simulate.signals import bump, plateau, ramp, smooth_noise

TABLE_HEIGHT_M = 0.75
BAG_JOLT_GAIN = 3.0  # the bag knocks against the body at each heel strike, harder than the hand feels it

# Base orientation of the phone in each placement, in its segment's frame (columns: where the
# device's x, y, z axes point). Segment: torso for texting, forearm for swinging, head for call,
# thigh / pelvis for pockets.
_TEXTING = from_axes((0, -1, 0), (1, 0, 0), (0, 0, 1))  # screen up, top forward
_SWINGING = from_axes((1, 0, 0), (0, 0, -1), (0, 1, 0))  # top towards the fingers, screen inwards
_CALL = from_axes((-1, 0, 0), (0, 0, 1), (0, 1, 0))  # screen against the right ear, top up
_FRONT_POCKET = from_axes((0, 1, 0), (0, 0, 1), (1, 0, 0))  # top up, screen facing forward
_BACK_POCKET = from_axes((0, -1, 0), (0, 0, 1), (-1, 0, 0))  # top up, screen facing backward
_WATCH = from_axes((0, 0, -1), (-1, 0, 0), (0, 1, 0))  # face out of the back of the wrist
_EARBUD = rot_z(0.5) @ rot_x(-0.3)  # stem down and forward in the ear
_FLIPS = (np.eye(3), rot_z(np.pi), rot_y(np.pi), rot_z(np.pi) @ rot_y(np.pi))


def _flip(rng) -> np.ndarray:
    return _FLIPS[int(rng.integers(0, 4))]


class PosePath:
    """Base class: ``pose(t) -> (pos (N,3), R (N,3,3))`` of a device, world frame."""

    def pose(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover
        raise NotImplementedError

    def worn(self, t: np.ndarray) -> np.ndarray:
        return np.ones(np.shape(t), dtype=bool)


class Earbuds(PosePath):
    def __init__(self, body: Body, rng: np.random.Generator):
        self.body = body
        self.mount = _EARBUD @ random_rotation(rng, 15.0)

    def pose(self, t):
        st = self.body.evaluate(t)
        return st.head + apply(st.R_head, np.array([0.0, -0.075, 0.0])), st.R_head @ self.mount


class Watch(PosePath):
    def __init__(self, body: Body, rng: np.random.Generator):
        self.body = body
        self.mount = _WATCH @ random_rotation(rng, 10.0)
        self.offset = np.array([0.0, 0.028, -0.93 * body.forearm_m])

    def pose(self, t):
        st = self.body.evaluate(t)
        return st.l_elbow + apply(st.R_l_forearm, self.offset), st.R_l_forearm @ self.mount


class Phone(PosePath):
    """The phone following the scenario's placement holds, moved smoothly between them."""

    def __init__(self, body: Body, scenario: Scenario, rng: np.random.Generator):
        self.body = body
        self.holds = scenario.holds
        T = scenario.duration
        # People hold a phone in either hand; the left one is also the watch arm.
        self.hand = "left" if rng.uniform() < 0.35 else "right"
        side = 1.0 if self.hand == "left" else -1.0  # +y is the walker's left
        self.mounts = {
            "texting": _TEXTING @ rot_x(rng.uniform(25, 50) * np.pi / 180) @ random_rotation(rng, 6.0),
            "swinging": _SWINGING @ (_FLIPS[2] if rng.uniform() < 0.5 else np.eye(3)) @ random_rotation(rng, 12.0),
            "call": _CALL @ rot_z(-rng.uniform(30, 55) * np.pi / 180) @ random_rotation(rng, 10.0),
            "front_pocket": _FRONT_POCKET @ _flip(rng) @ random_rotation(rng, 12.0),
            "back_pocket": _BACK_POCKET @ _flip(rng) @ random_rotation(rng, 12.0),
            "bag": random_rotation(rng),
        }
        # the hand is never perfectly still: slow wander of the held phone
        self.wander_pos = smooth_noise(rng, -2, T + 2, 0.7, 0.008, dims=3)
        self.wander_rot = smooth_noise(rng, -2, T + 2, 0.9, 2.0 * np.pi / 180, dims=3)
        self.texting_offset = np.array([rng.uniform(0.22, 0.32), side * rng.uniform(0.02, 0.12), -0.17])
        self.ear_offset = np.array([0.03, side * 0.10, -0.03])
        if self.hand == "left":  # the screen faces the other ear
            self.mounts["call"] = rot_z(np.pi) @ self.mounts["call"]
        # a phone held in front bobs with each step (pitch) and sways with each stride (roll, yaw)
        bob = body.s.hand_bob_deg * np.pi / 180
        self.bob_amp = bob * np.array([0.7, 1.0, 0.6]) * rng.uniform(0.7, 1.3, 3)
        self.bob_phase = rng.uniform(0, 2 * np.pi, 3)
        self.shakes = [d for d in scenario.disturbances if d.kind == "phone_shake"]
        self.bag = _Bag(body, rng, T) if any(h.placement == "bag" for h in self.holds) else None
        # fixed relative rotation of each move, taken mid-move (see blend_rotations)
        self.deltas = []
        for a, b in zip(self.holds[:-1], self.holds[1:]):
            tm = np.array([0.5 * (a.end + b.start)])
            st = body.evaluate(tm)
            _, RA = self._hold_pose(a.placement, st)
            _, RB = self._hold_pose(b.placement, st)
            self.deltas.append(log_so3(RA[0].T @ RB[0]))

    # -- one placement ----------------------------------------------------------------------
    def _hold_pose(self, placement: str, st: BodyState):
        t = st.t
        M = self.mounts[placement]
        if placement == "texting":
            F = rot_z(st.theta + 0.5 * st.yaw_torso) @ rot_y(st.pitch_torso_slow)
            pos = st.chest + apply(F, self.texting_offset) + self.wander_pos(t)
            # the held forearm amplifies the trunk's bounce, and rises and falls a little with each stride
            hb = self.body.s.hand_bounce_m * st.env
            pos[:, 2] += st.heel + hb * (
                np.cos(st.phase + self.bob_phase[0]) + 0.6 * np.sin(0.5 * st.phase + self.bob_phase[1])
            )
            psi = 0.5 * st.phase
            bob = st.env[:, None] * self.bob_amp * np.sin(np.stack([psi, st.phase, psi], 1) + self.bob_phase)
            R = F @ M @ exp_so3(self.wander_rot(t) + bob)
        elif placement == "swinging":
            elbow, R_fa = (st.l_elbow, st.R_l_forearm) if self.hand == "left" else (st.r_elbow, st.R_r_forearm)
            pos = elbow + apply(R_fa, np.array([0.02, 0.0, -(self.body.forearm_m + 0.06)]))
            R = R_fa @ M
        elif placement == "call":
            pos = st.head + apply(st.R_head, self.ear_offset) + 0.5 * self.wander_pos(t)
            R = st.R_head @ M @ exp_so3(0.5 * self.wander_rot(t))
        elif placement == "front_pocket":
            pos = st.r_hip + apply(st.R_r_thigh, np.array([0.075, -0.02, -0.18]))
            R = st.R_r_thigh @ M
        elif placement == "back_pocket":
            R_seat = st.R_pelvis @ rot_y(-0.3 * st.r_hip_flex)  # the buttock follows the leg a little
            pos = st.r_hip + apply(R_seat, np.array([-0.11, 0.02, -0.07]))
            R = R_seat @ M
        elif placement == "bag":
            assert self.bag is not None  # built whenever a hold is in the bag
            pos, R = self.bag.pose(st)
            pos = pos + (BAG_JOLT_GAIN * st.heel)[:, None] * np.array([0.0, 0.0, 1.0])  # knocks on each step
            R = R @ M
        else:  # pragma: no cover - config validation prevents this
            raise ValueError(placement)
        if placement in ("texting", "swinging", "call") and self.shakes:
            for d in self.shakes:
                env = plateau(t, d.start, d.start + 0.3, d.end - 0.3, d.end)
                if not env.any():
                    continue
                arg = 2 * np.pi * d.freq_hz * (t - d.start)
                R = R @ exp_so3((env * d.amp * np.sin(arg))[:, None] * np.asarray(d.axis))
                pos = pos + (env * 0.02 * np.sin(arg + 1.0))[:, None] * np.array([0.0, 0.0, 1.0])
        return pos, R

    # -- the schedule -------------------------------------------------------------------------
    def pose(self, t):
        t = np.asarray(t, dtype=np.float64)
        st = self.body.evaluate(t)
        pos = np.empty((t.size, 3))
        R = np.empty((t.size, 3, 3))
        holds = self.holds
        for i, h in enumerate(holds):
            lo = -np.inf if i == 0 else h.start
            hi = np.inf if i == len(holds) - 1 else h.end
            m = (t >= lo) & (t <= hi)
            if m.any():
                pos[m], R[m] = self._hold_pose(h.placement, st.take(m))
        for i, (a, b) in enumerate(zip(holds[:-1], holds[1:])):
            m = (t > a.end) & (t < b.start)
            if not m.any():
                continue
            sub = st.take(m)
            pa, Ra = self._hold_pose(a.placement, sub)
            pb, Rb = self._hold_pose(b.placement, sub)
            w = ramp(sub.t, a.end, b.start)
            # the hand takes the phone out and away from the body on the way
            out = (
                bump(sub.t, a.end, b.start)[:, None]
                * 0.10
                * np.stack([np.sin(sub.theta), -np.cos(sub.theta), np.zeros_like(sub.theta)], 1)
            )
            pos[m] = (1 - w)[:, None] * pa + w[:, None] * pb + out
            R[m] = blend_rotations(Ra, Rb, w, self.deltas[i])
        return pos, R


class _Bag:
    """A bag hanging from the torso: backpack (stiff) or shoulder bag (looser), lagging the body.

    The bag's displacement relative to its strap anchor obeys x'' + 2ζω x' + ω² x = −a_anchor
    (a driven spring-damper in the world frame), solved on the motion grid and splined; its
    orientation tilts with the displacement like a short pendulum and turns with the torso.
    """

    def __init__(self, body: Body, rng, T: float):
        self.body = body
        self.kind = "backpack" if rng.uniform() < 0.5 else "shoulder_bag"
        if self.kind == "backpack":
            f_n, zeta, self.anchor, self.strap = rng.uniform(2.5, 4.0), rng.uniform(0.2, 0.4), "back", 0.35
        else:
            f_n, zeta, self.anchor, self.strap = rng.uniform(1.3, 2.0), rng.uniform(0.12, 0.25), "side", 0.6
        dt = 1.0 / GRID_HZ
        t = np.arange(-1.5, T + 1.5, dt)
        p = self._anchor(body.evaluate(t))
        acc = np.gradient(np.gradient(p, dt, axis=0), dt, axis=0)
        w = 2 * np.pi * f_n
        b, a, _ = cont2discrete(([-1.0], [1.0, 2 * zeta * w, w * w]), dt, method="bilinear")
        lag = lfilter(np.ravel(b), a, acc, axis=0)
        self.lag = CubicSpline(t, lag, axis=0)
        self.meta = {"bag": self.kind, "bag_natural_hz": round(float(f_n), 3), "bag_damping": round(float(zeta), 3)}

    def _anchor(self, st: BodyState) -> np.ndarray:
        if self.anchor == "back":
            return st.chest + apply(st.R_torso, np.array([-0.22, 0.0, -0.05]))
        return st.pelvis + apply(st.R_pelvis, np.array([0.0, -0.22, 0.05]))

    def pose(self, st: BodyState):
        lag = self.lag(st.t)
        fwd = lag[:, 0] * np.cos(st.theta) + lag[:, 1] * np.sin(st.theta)
        lat = -lag[:, 0] * np.sin(st.theta) + lag[:, 1] * np.cos(st.theta)
        R = (
            rot_z(st.theta + 0.5 * st.yaw_torso)
            @ rot_y(st.pitch_torso_slow + fwd / self.strap)
            @ rot_x(-lat / self.strap)
        )
        return self._anchor(st) + lag, R


class Removed(PosePath):
    """DRW wrapper: the device comes off at ``removal.start``. Variant ``table``: it is carried
    to a table beside the path over [start, end] and then lies still; ``stop``: the pose is that
    of the worn device (its stream is simply cut at ``start`` by the caller)."""

    def __init__(self, worn: PosePath, removal: Removal, body: Body, rng: np.random.Generator):
        self.inner = worn
        self.removal = removal
        self.table_pos = self.table_R = None
        if removal.variant == "table":
            tm = removal.start + 0.6 * (removal.end - removal.start)
            p_ref, R_ref = worn.pose(np.array([tm]))
            theta = body.evaluate(np.array([tm])).theta[0]
            side = np.array([-np.sin(theta), np.cos(theta), 0.0]) * rng.uniform(0.25, 0.45)
            self.table_pos = np.array([p_ref[0, 0], p_ref[0, 1], TABLE_HEIGHT_M]) + side
            lying = np.eye(3) if isinstance(worn, Watch) else rot_x(np.pi / 2)  # watch face up / bud on its side
            self.table_R = rot_z(rng.uniform(-np.pi, np.pi)) @ lying
            self.delta = log_so3(R_ref[0].T @ self.table_R)

    def pose(self, t):
        pos, R = self.inner.pose(t)
        if self.table_pos is None:
            return pos, R
        assert self.table_R is not None  # set with table_pos
        m = t > self.removal.start
        if m.any():
            w = ramp(t[m], self.removal.start, self.removal.end)
            pos[m] = (1 - w)[:, None] * pos[m] + w[:, None] * self.table_pos
            R[m] = blend_rotations(R[m], np.broadcast_to(self.table_R, R[m].shape), w, self.delta)
        return pos, R

    def worn(self, t):
        return np.asarray(t) < self.removal.start
