"""Body segment kinematics: pelvis, torso, head, both arms and the right thigh.

A small rigid-segment model driven by the gait phase φ (2π per step; ψ = φ/2 per stride) and the
walking envelope e (0 standing … 1 walking) of :class:`~wearnav.simulate.path.BaseMotion`:

- pelvis: vertical bounce at step frequency (with a second harmonic), lateral sway towards the
  stance leg at stride frequency, fore-aft ripple at step frequency; pelvic yaw/roll at stride
  frequency;
- torso: forward lean, pitch oscillation at step frequency, yaw counter-rotating to the pelvis;
- head: follows the neck, partly stabilised in yaw, slow looking-around, gaze slightly down;
- arms: pendulum swing at stride frequency in antiphase with the same-side leg (left arm forward
  while the left leg is back), elbow flexion swinging with it;
- thigh: hip flexion/extension at stride frequency.

Daily-living episodes (DLW) lower the pelvis, lean the torso and flex hips and arms through smooth
posture transitions; MVW disturbances add wrist shakes and head tilts. Segment dimensions are
fractions of stature (Winter's anthropometric table). Segment frames: x forward, y left, z up
(along the segment, for limbs).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from wearnav.simulate.config import SubjectParams
from wearnav.simulate.geometry import apply, rot_x, rot_y, rot_z
from wearnav.simulate.path import BaseMotion
from wearnav.simulate.scenario import Scenario
from wearnav.simulate.signals import bump, plateau, smooth_noise

DEG = np.pi / 180.0
IMPACT_S = 0.022  # std of the heel-strike transient
LEG_IMPACT_S = 0.016  # std (duration) of the heel-strike acceleration spike at the thigh
THIGH_WOBBLE_KNOT_S = 0.06  # correlation time of the thigh's irregular soft-tissue motion
IMPACT_HARMONICS = 24  # harmonics of the stride frequency in the impact train (to ~20 Hz)
HAND_IMPACT_S = 0.02  # the arm smooths the heel-strike shock before it reaches the hands


def impact_train(phase: np.ndarray, at: float, width: float, rate: float) -> np.ndarray:
    """Displacement (m per m/s² of peak) whose acceleration is a train of Gaussian spikes, one
    each time ``phase`` (advancing at ``rate`` rad/s) passes ``at``, of std ``width`` (rad),
    with the mean removed: what a heel strike does to a limb — a short hard deceleration, paid
    back gently over the rest of the cycle. A Fourier series, so it is smooth and periodic."""
    k = np.arange(1, IMPACT_HARMONICS + 1)
    w = np.exp(-0.5 * (k * width) ** 2)
    coef = w / k**2
    # Σ coef_k cos(k x) by the Chebyshev recurrence cos(kx) = 2 cos(x) cos((k−1)x) − cos((k−2)x):
    # one cosine per sample instead of one per harmonic
    c1 = np.cos(np.asarray(phase, dtype=np.float64) - at)
    prev, cur = np.ones_like(c1), c1
    out = coef[0] * cur
    for ck in coef[1:]:
        prev, cur = cur, 2.0 * c1 * cur - prev
        out += ck * cur
    return -out / (w.sum() * rate**2)


# Posture of each daily-living episode while held (rad / m); "lean_move" is the extra forward
# lean in the middle of sitting down or getting up (people lean forward to shift their weight).
POSTURES = {
    "sit": dict(
        seat_m=0.50, back_m=0.12, lean=-0.06, lean_move=0.45, hip=1.45, l_shoulder=0.35, l_elbow=0.9, head=0.10
    ),
    "squat": dict(
        seat_m=0.36, back_m=0.10, lean=0.60, lean_move=0.15, hip=1.90, l_shoulder=0.55, l_elbow=0.25, head=0.35
    ),
}


@dataclass
class BodyState:
    """Segment poses at times ``t`` (world frame; rotations map segment → world)."""

    t: np.ndarray
    theta: np.ndarray  # heading of progression
    env: np.ndarray  # walking envelope
    yaw_torso: np.ndarray  # trunk yaw oscillation relative to the heading
    pitch_torso_slow: np.ndarray  # trunk lean without the gait oscillation
    pelvis: np.ndarray
    R_pelvis: np.ndarray
    chest: np.ndarray
    R_torso: np.ndarray
    head: np.ndarray  # head centre (between the ears)
    R_head: np.ndarray
    l_elbow: np.ndarray
    R_l_forearm: np.ndarray
    r_elbow: np.ndarray
    R_r_forearm: np.ndarray
    r_hip: np.ndarray
    R_r_thigh: np.ndarray
    r_hip_flex: np.ndarray
    phase: np.ndarray  # gait phase φ (2π per step)
    heel: np.ndarray  # vertical displacement (m) of the heel-strike shock felt at the hands, both feet

    def take(self, idx) -> BodyState:
        return BodyState(**{f.name: getattr(self, f.name)[idx] for f in fields(self)})

    def __len__(self) -> int:
        return int(self.t.size)


class Body:
    """Evaluates :class:`BodyState` at arbitrary times (vectorised)."""

    def __init__(self, subject: SubjectParams, scenario: Scenario, base: BaseMotion, rng: np.random.Generator):
        self.s = subject
        self.base = base
        self.scenario = scenario
        T = scenario.duration
        # slow, smooth head motions: looking around, up/down, a little roll
        self.head_yaw = smooth_noise(rng, -2, T + 2, 3.0, subject.head_yaw_deg * DEG)
        self.head_pitch = smooth_noise(rng, -2, T + 2, 2.5, 3.0 * DEG)
        self.head_roll = smooth_noise(rng, -2, T + 2, 4.0, 1.5 * DEG)
        self.episodes = [e for e in scenario.episodes if e.kind in POSTURES]
        self.wrist_shakes = [d for d in scenario.disturbances if d.kind == "wrist_shake"]
        self.head_tilts = [d for d in scenario.disturbances if d.kind == "head_tilt"]
        # step-to-step amplitude variability, correlated over about one step
        self.step_amp = smooth_noise(rng, -2, T + 2, 1.0 / subject.cadence_hz, subject.step_amp_cv)
        # the thigh's soft tissue wobbles irregularly (5–10 Hz) under a pocket
        self.thigh_wobble = smooth_noise(rng, -2, T + 2, THIGH_WOBBLE_KNOT_S, subject.thigh_wobble_mm * 1e-3, dims=3)

    @property
    def hip_height(self) -> float:
        return 0.53 * self.s.height_m

    def _posture(self, t):
        """Posture offsets (drop, back, lean, hip, l_shoulder, l_elbow, head) at times t."""
        out = {k: np.zeros_like(t) for k in ("drop", "back", "lean", "hip", "l_shoulder", "l_elbow", "head")}
        for e in self.episodes:
            p = POSTURES[e.kind]
            assert e.down is not None and e.up is not None  # the body's episodes are sit or squat stops
            hold = plateau(t, e.down[0], e.down[1], e.up[0], e.up[1])
            moving = bump(t, *e.down) + bump(t, *e.up)
            out["drop"] += (self.hip_height - p["seat_m"]) * hold
            out["back"] += p["back_m"] * hold
            out["lean"] += p["lean"] * hold + p["lean_move"] * moving
            for k in ("hip", "l_shoulder", "l_elbow", "head"):
                out[k] += p[k] * hold
        return out

    def _disturbances(self, t):
        pron = np.zeros_like(t)
        elbow = np.zeros_like(t)
        for d in self.wrist_shakes:
            env = plateau(t, d.start, d.start + 0.3, d.end - 0.3, d.end)
            arg = 2 * np.pi * d.freq_hz * (t - d.start)
            pron += env * d.amp * np.sin(arg)
            elbow += env * 0.15 * d.amp * np.sin(arg + 1.0)
        head = np.zeros(t.shape + (3,))
        for d in self.head_tilts:
            ramp_s = min(0.6, (d.end - d.start) / 3)
            head[:, int(d.axis[0])] += d.amp * plateau(t, d.start, d.start + ramp_s, d.end - ramp_s, d.end)
        return pron, elbow, head

    def evaluate(self, t) -> BodyState:
        t = np.asarray(t, dtype=np.float64)
        s, H = self.s, self.s.height_m
        c = self.base(t)
        x, y, theta, phi, a = (
            c[:, i] for i in (BaseMotion.X, BaseMotion.Y, BaseMotion.THETA, BaseMotion.PHASE, BaseMotion.ENV)
        )
        a = np.clip(a, 0.0, 1.0)
        # Gait amplitude grows with speed: with cadence ∝ v^0.5 (path) the step grows ∝ v^0.5 and
        # the pendulum's rise ∝ step² ∝ v (config.pendulum_excursion), so linearly in v/v₀.
        amp = a * np.clip(c[:, BaseMotion.SPEED_RATIO], 0.8, 1.2)
        amp = amp * (1.0 + 0.5 * np.tanh(2.0 * self.step_amp(t)))  # smooth (C²) limit to 0.5 … 1.5
        psi = 0.5 * phi
        post = self._posture(t)
        pron, elbow_shake, head_dist = self._disturbances(t)

        # ---- pelvis ----------------------------------------------------------------------
        u = np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], 1)
        n = np.stack([-np.sin(theta), np.cos(theta), np.zeros_like(theta)], 1)
        # The second harmonic (minus sign) makes the vertical acceleration peak sharply at double
        # support (CoM lowest, φ = π) and trough broadly at mid-stance (CoM highest, φ = 0).
        bounce = 0.5 * s.bounce_m * amp * (np.cos(phi) - s.bounce_harmonic * np.cos(2 * phi + 0.3))
        bounce *= 1.0 + s.step_asymmetry * np.sin(psi)  # one leg's steps a little stronger
        sway = -0.5 * s.sway_m * amp * np.cos(psi)  # towards the stance leg
        # Inverted pendulum: the body is slowest at mid-stance (φ = 0, CoM highest) and fastest at
        # double support, so the fore-aft acceleration ∝ sin(φ + p) peaks ≈ 90° + p before the
        # vertical one (real hand-held phones, ILC2: forward leads vertical by 96° on average).
        ripple = -0.5 * s.ripple_m * amp * np.sin(phi + s.ripple_phase_rad)
        # Heel strike (at φ = π, double support): a brief dip of the pelvis, i.e. an upward
        # acceleration spike of about impact/σ² (1–2.5 m/s²), damped by the spine before the head.
        width = 2 * np.pi * s.cadence_hz * IMPACT_S
        dphi = (phi % (2 * np.pi)) - np.pi
        impact = -1e-3 * s.impact_mm * amp * np.exp(-0.5 * (dphi / width) ** 2)
        pelvis = np.stack([x, y, np.full_like(x, self.hip_height)], 1)
        pelvis[:, 2] += bounce + impact - post["drop"]
        pelvis += u * (ripple - post["back"])[:, None] + n * sway[:, None]
        yaw_pelvis = -1.3 * s.trunk_yaw_deg * DEG * amp * np.sin(psi)
        roll_pelvis = 3.0 * DEG * amp * np.sin(psi + 1.2)
        R_pelvis = rot_z(theta + yaw_pelvis) @ rot_x(roll_pelvis)

        # ---- torso -----------------------------------------------------------------------
        yaw_torso = s.trunk_yaw_deg * DEG * amp * np.sin(psi)  # counter-rotates to the pelvis
        pitch_slow = s.trunk_lean_deg * DEG * (0.4 + 0.6 * a) + post["lean"]
        pitch = pitch_slow + 0.7 * DEG * amp * np.sin(phi + 0.5)
        roll = s.trunk_roll_deg * DEG * amp * np.sin(psi + 1.2)
        R_torso = rot_z(theta + yaw_torso) @ rot_y(pitch) @ rot_x(roll)
        chest = pelvis + apply(R_torso, np.array([0.10, 0.0, 0.19 * H]))
        neck = pelvis + apply(R_torso, np.array([0.0, 0.0, 0.288 * H]))

        # ---- head (stabilised: follows the heading more than the trunk's oscillations) ----
        R_head = (
            rot_z(theta + 0.3 * yaw_torso + self.head_yaw(t) + head_dist[:, 2])
            @ rot_y(
                s.head_pitch_deg * DEG
                + 0.3 * (pitch - pitch_slow)
                + self.head_pitch(t)
                + post["head"]
                + head_dist[:, 1]
            )
            @ rot_x(0.3 * roll + self.head_roll(t) + head_dist[:, 0])
        )
        head = neck + apply(R_head, np.array([0.02, 0.0, 0.10 * H]))
        head[:, 2] -= 0.7 * impact

        # ---- arms: swing at stride frequency, antiphase with the same-side leg -------------
        A = s.arm_swing_deg * DEG
        swing = amp * A * np.sin(psi + s.arm_lag_rad)  # > 0: right arm forward, left arm back
        elbow_swing = amp * 0.3 * A * np.sin(psi + s.arm_lag_rad + 0.3)
        upper = 0.186 * H
        sh_l = pelvis + apply(R_torso, np.array([0.0, 0.105 * H, 0.27 * H]))
        R_ua_l = R_torso @ rot_y(-(post["l_shoulder"] - swing)) @ rot_x(np.full_like(t, 0.08))
        l_elbow = sh_l + apply(R_ua_l, np.array([0.0, 0.0, -upper]))
        flex_l = np.maximum(s.elbow_deg * DEG + post["l_elbow"] - elbow_swing + elbow_shake, 0.02)
        wobble = amp * s.wrist_wobble_deg * DEG * np.sin(phi + 0.7)  # forearm roll with each step
        R_l_forearm = R_ua_l @ rot_y(-flex_l) @ rot_z(pron + wobble)
        sh_r = pelvis + apply(R_torso, np.array([0.0, -0.105 * H, 0.27 * H]))
        R_ua_r = R_torso @ rot_y(-swing) @ rot_x(np.full_like(t, -0.08))
        r_elbow = sh_r + apply(R_ua_r, np.array([0.0, 0.0, -upper]))
        flex_r = np.maximum(s.elbow_deg * DEG + elbow_swing, 0.02)
        R_r_forearm = R_ua_r @ rot_y(-flex_r)

        # ---- right thigh ---------------------------------------------------------------------
        hip_flex_r = post["hip"] - amp * s.hip_swing_deg * DEG * np.sin(psi)
        r_hip = pelvis + apply(R_pelvis, np.array([0.0, -0.05 * H, 0.0]))
        R_r_thigh = R_pelvis @ rot_y(-hip_flex_r)
        # Heel strike decelerates the thigh hard (right heel strike at ψ = 3π/2, where the leg
        # is furthest forward; the left one, through the pelvis, at ψ = π/2): a sharp dip and a
        # backward jerk of the leg, the large short peaks a pocketed phone records.
        omega_stride = np.pi * s.cadence_hz
        jolt = s.leg_impact * amp * impact_train(psi, 1.5 * np.pi, omega_stride * LEG_IMPACT_S, omega_stride)
        r_hip[:, 2] += jolt  # upward spike: the downward motion of the leg is stopped
        r_hip -= u * (0.3 * jolt)[:, None]  # and its forward swing
        r_hip += a[:, None] * self.thigh_wobble(t)
        omega_step = 2 * np.pi * s.cadence_hz
        heel = s.hand_impact * amp * impact_train(phi, np.pi, omega_step * HAND_IMPACT_S, omega_step)
        l_elbow[:, 2] += heel
        r_elbow[:, 2] += heel

        return BodyState(
            t=t,
            theta=theta,
            env=a,
            yaw_torso=yaw_torso,
            pitch_torso_slow=pitch_slow,
            pelvis=pelvis,
            R_pelvis=R_pelvis,
            chest=chest,
            R_torso=R_torso,
            head=head,
            R_head=R_head,
            l_elbow=l_elbow,
            R_l_forearm=R_l_forearm,
            r_elbow=r_elbow,
            R_r_forearm=R_r_forearm,
            r_hip=r_hip,
            R_r_thigh=R_r_thigh,
            r_hip_flex=hip_flex_r,
            phase=phi,
            heel=heel,
        )

    @property
    def forearm_m(self) -> float:
        """Elbow to wrist; devices at the hand are placed along the forearm frame's −z."""
        return 0.146 * self.s.height_m
