"""Configuration of one simulated walk: the subject's body and gait, and the walk's conditions.

Defaults and ranges follow Suite-IN++ (Sec. III, Table II): phone and watch at 100 Hz, earbuds at
25 Hz, walking modes STW/PVW/MVW/DRW/DLW, recording-level phone placements HD/MP/PK/BG, areas
small (< 30 m), medium (< 50 m) and large (> 100 m).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any

import numpy as np

from wearnav.errors import ConfigError

MODES = ("STW", "PVW", "MVW", "DRW", "DLW")
# Recording-level phone placement (Suite-IN++ Table IV): handheld, multi-changed, pocket, bag.
PLACEMENTS = ("HD", "MP", "PK", "BG")
# Fine-grained phone placements (the "placement" label track).
PHONE_HOLDS = ("texting", "swinging", "call", "front_pocket", "back_pocket", "bag")
HOLDS_OF_PLACEMENT = {
    "HD": ("texting", "swinging"),
    "PK": ("front_pocket", "back_pocket"),
    "BG": ("bag",),
    "MP": ("texting", "swinging", "call", "front_pocket", "back_pocket"),
}
HAND_HOLDS = ("texting", "swinging", "call")
# Side length ranges (m) of the square walking area per scene (Suite-IN++ Table I footnote).
SCENES = {"small": (18.0, 30.0), "medium": (32.0, 50.0), "large": (100.0, 150.0)}
NOISE_LEVELS = ("L1", "L2", "L3")
DEVICES = ("phone", "watch", "earbuds")
REMOVABLE = ("watch", "earbuds")
REMOVAL_VARIANTS = ("table", "stop")


@dataclass(frozen=True)
class SubjectParams:
    """One walker's body and gait. Amplitudes are of the torso (pelvis) unless named otherwise."""

    name: str = "u1"
    height_m: float = 1.75
    speed_mps: float = 1.3  # preferred walking speed
    cadence_hz: float = 1.9  # steps per second at the preferred speed
    bounce_m: float = 0.035  # vertical peak-to-peak, at step frequency
    sway_m: float = 0.04  # lateral peak-to-peak, at stride frequency (half the step frequency)
    ripple_m: float = 0.025  # fore-aft peak-to-peak about the mean progression, at step frequency
    bounce_harmonic: float = 0.08  # second-harmonic share of the bounce
    impact_mm: float = 0.8  # heel-strike dip of the pelvis (a ~22 ms Gaussian), mm
    ripple_phase_rad: float = 0.1  # fore-aft acceleration leads the vertical by 90° + this
    trunk_lean_deg: float = 5.0
    trunk_yaw_deg: float = 3.0  # trunk rotation amplitude at stride frequency
    trunk_roll_deg: float = 2.0
    hip_swing_deg: float = 22.0  # thigh flexion/extension amplitude
    arm_swing_deg: float = 15.0  # shoulder flexion/extension amplitude
    elbow_deg: float = 20.0  # mean elbow flexion while walking
    arm_lag_rad: float = -0.2  # arm swing phase relative to exact antiphase with the same-side leg
    head_yaw_deg: float = 8.0  # std of slow looking-around
    head_pitch_deg: float = 8.0  # mean downward gaze
    # Step-to-step variability (real gait is not periodic; calibrated in docs/realism.md):
    step_time_cv: float = 0.07  # relative std of the step frequency from one step to the next
    step_amp_cv: float = 0.3  # relative std of the gait amplitude from one step to the next
    step_asymmetry: float = 0.08  # left/right difference of the vertical bounce (share)
    leg_impact: float = 17.0  # peak heel-strike acceleration of the thigh (under a pocket), m/s²
    thigh_wobble_mm: float = 0.6  # irregular 5–10 Hz soft-tissue motion under a pocket, mm (std)
    hand_impact: float = 2.2  # peak heel-strike acceleration reaching the hands and wrists, m/s²
    hand_bob_deg: float = 3.5  # step-synchronous rotation of a phone held in front of the body
    hand_bounce_m: float = 0.012  # the forearm held in front amplifies the trunk's bounce
    wrist_wobble_deg: float = 8.0  # forearm roll (pronation) oscillation at step frequency

    @property
    def step_length_m(self) -> float:
        return self.speed_mps / self.cadence_hz


# Gait coupled to speed (sample_subject). Between walkers, preferred cadence rises with speed
# more weakly than within one walker (path.BaseMotion: cadence ∝ v^0.5; Kuo 2001: step length
# ∝ v^0.42 within subjects), because faster walkers are mostly taller ones with longer steps;
# the exponent is also bounded by the real walkers' cadence (1.66–1.88 steps/s, docs/realism.md)
# over this population's wide speed range.
CADENCE_MEDIAN_HZ = 1.77  # at the median speed; the real bands leave little room (docs/realism.md): 1.76
# put the bag's f_dom median at its band's lower edge (1.753), 1.77 the hand's near its upper one (1.791)
SPEED_MEDIAN_MPS = 1.16  # of the accepted walkers (the step-length limits trim fast short ones)
CADENCE_SPEED_EXP = 0.22
CADENCE_JITTER = 0.012  # relative std of a walker's own cadence at a given speed
LEG_OF_HEIGHT = 0.53  # leg length / stature (Winter), the pendulum's length
KNEE_FLEXION = 0.6  # stance knee flexion flattens the compass gait's arc (Saunders et al. 1953)
BOUNCE_JITTER = 0.15  # a walker's own bounce at a given step length: ×(1 ± this), uniform


def pendulum_excursion(step_m: float, leg_m: float) -> float:
    """Rise of the hip over a stiff-legged step: a leg of length l vaulting over the stance foot,
    half a step s on either side, h = l·(1 − cos(asin(s / 2l))); the inverse of Zijlstra & Hof's
    (2003) step-length estimate s = 2·√(2lh − h²) from the trunk's vertical excursion."""
    return leg_m * (1.0 - np.cos(np.arcsin(step_m / (2.0 * leg_m))))


def sample_subject(rng: np.random.Generator, name: str) -> SubjectParams:
    """A random but plausible walker: speed 0.85–1.55 m/s, step 0.45–0.85 m, cadence rising with
    speed (1.77 · (v / 1.16)^0.22 steps/s, ±1.2 % per walker; the population's cadence is about
    1.77 ± 0.07 within 1.6–2.0, 10–90 % in 1.68–1.86, like the real walkers in the shipped
    recordings, 1.66–1.88, docs/realism.md), a vertical bounce that is the inverted-pendulum rise
    of its step over its leg (:func:`pendulum_excursion` × knee flexion 0.6, ± 15 % uniform: 10–90 % in
    2.5–5.3 cm), a hand bounce in proportion (0.26–0.42 of it),
    and its own step-to-step variability. Fast walkers thus step faster and bounce more, as real
    ones do, so their speed can be told from the IMU (Weinberg's step-length model relies on it)."""
    # One draw per field as before the coupling, so a seed's walkers keep their other traits.
    height = float(rng.uniform(1.55, 1.92))
    while True:
        speed = float(rng.uniform(0.85, 1.55))
        cadence = CADENCE_MEDIAN_HZ * (speed / SPEED_MEDIAN_MPS) ** CADENCE_SPEED_EXP
        cadence = float(np.clip(cadence * (1.0 + CADENCE_JITTER * rng.standard_normal()), 1.6, 2.0))
        step = speed / cadence
        # Step length scales with stature (about 0.26 H … 0.47 H at normal speeds).
        if 0.45 <= step <= 0.85 and 0.25 * height <= step <= 0.47 * height:
            break
    rise = KNEE_FLEXION * pendulum_excursion(step, LEG_OF_HEIGHT * height)
    bounce = rise * float(rng.uniform(1.0 - BOUNCE_JITTER, 1.0 + BOUNCE_JITTER))
    return SubjectParams(
        name=name,
        height_m=round(height, 3),
        speed_mps=round(speed, 3),
        cadence_hz=round(cadence, 3),
        bounce_m=round(bounce, 4),
        sway_m=round(float(rng.uniform(0.025, 0.055)), 4),
        ripple_m=round(float(rng.uniform(0.015, 0.035)), 4),
        bounce_harmonic=round(float(rng.uniform(0.0, 0.12)), 3),
        impact_mm=round(float(rng.uniform(0.5, 1.2)), 3),
        ripple_phase_rad=round(float(rng.uniform(-0.3, 0.5)), 3),
        trunk_lean_deg=round(float(rng.uniform(2.0, 9.0)), 2),
        trunk_yaw_deg=round(float(rng.uniform(2.0, 5.0)), 2),
        trunk_roll_deg=round(float(rng.uniform(1.0, 3.0)), 2),
        hip_swing_deg=round(float(rng.uniform(22.0, 30.0)), 2),
        arm_swing_deg=round(float(rng.uniform(10.0, 20.0)), 2),
        elbow_deg=round(float(rng.uniform(12.0, 30.0)), 2),
        arm_lag_rad=round(float(rng.uniform(-0.4, 0.1)), 3),
        head_yaw_deg=round(float(rng.uniform(4.0, 12.0)), 2),
        head_pitch_deg=round(float(rng.uniform(2.0, 15.0)), 2),
        step_time_cv=round(float(rng.uniform(0.05, 0.09)), 4),
        step_amp_cv=round(float(rng.uniform(0.2, 0.4)), 4),
        step_asymmetry=round(float(rng.uniform(0.06, 0.2)), 4),
        leg_impact=round(float(rng.uniform(12.0, 22.0)), 3),
        thigh_wobble_mm=round(float(rng.uniform(0.4, 0.8)), 3),
        hand_impact=round(float(rng.uniform(1.5, 3.0)), 3),
        hand_bob_deg=round(float(rng.uniform(2.5, 4.5)), 3),
        hand_bounce_m=round(bounce * float(rng.uniform(0.26, 0.42)), 4),  # ≈ 0.008–0.016 at a 3.5 cm bounce
        wrist_wobble_deg=round(float(rng.uniform(5.0, 11.0)), 3),
    )


@dataclass(frozen=True)
class WalkConfig:
    """Everything that defines one simulated recording, apart from the random seed.

    ``phone_hold`` fixes the fine phone placement for the single-placement modes (None: drawn to
    match ``placement``); ``removal`` is ``"<device>:<variant>"`` for DRW, variant ``table`` (the
    device keeps streaming, lying still, ``worn`` False) or ``stop`` (its stream ends), None:
    drawn. ``imu_noise=False`` gives ideal sensors (exact specific force, body rate and
    orientation), for checking the physics.
    """

    name: str = "walk"
    subject: SubjectParams = field(default_factory=SubjectParams)
    mode: str = "STW"
    placement: str = "HD"
    scene: str = "medium"
    area_m: float | None = None
    duration_s: float = 60.0
    noise_level: str = "L1"
    devices: tuple[str, ...] = DEVICES
    imu_noise: bool = True
    speed_variation: float = 0.08  # relative std of the slow speed changes
    phone_hold: str | None = None
    removal: str | None = None
    truth_rate_hz: float = 100.0
    fix_rate_hz: float = 1.0
    fix_correlation_s: float = 120.0
    corridor_m: float | None = None  # a floor plan of corridors this wide (m) along the walker's own route

    def __post_init__(self) -> None:
        def bad(msg: str):
            raise ConfigError(f"walk config {self.name!r}: {msg}")

        if self.mode not in MODES:
            bad(f"unknown mode {self.mode!r} (expected one of {', '.join(MODES)})")
        if self.placement not in PLACEMENTS:
            bad(f"unknown placement {self.placement!r} (expected one of {', '.join(PLACEMENTS)})")
        if (self.placement == "MP") != (self.mode in ("PVW", "MVW")):
            bad(f"placement MP goes with modes PVW/MVW and only with them (got {self.mode}/{self.placement})")
        if self.scene not in SCENES:
            bad(f"unknown scene {self.scene!r} (expected one of {', '.join(SCENES)})")
        if self.noise_level not in NOISE_LEVELS:
            bad(f"unknown noise level {self.noise_level!r} (expected one of {', '.join(NOISE_LEVELS)})")
        unknown = [d for d in self.devices if d not in DEVICES]
        if unknown or not self.devices or "phone" not in self.devices:
            bad(f"devices must include 'phone' and come from {DEVICES}, got {self.devices}")
        if not 20.0 <= self.duration_s <= 7200.0:
            bad(f"duration_s must be within 20 … 7200 s, got {self.duration_s}")
        if self.mode == "DLW" and self.duration_s < 28.0:
            bad("DLW needs at least 28 s to fit walking around one daily-living episode")
        if self.phone_hold is not None:
            if self.phone_hold not in PHONE_HOLDS:
                bad(f"unknown phone_hold {self.phone_hold!r} (expected one of {PHONE_HOLDS})")
            if self.placement == "MP" or self.phone_hold not in HOLDS_OF_PLACEMENT[self.placement]:
                bad(f"phone_hold {self.phone_hold!r} does not fit placement {self.placement}")
        if self.removal is not None:
            dev, _, variant = self.removal.partition(":")
            if self.mode != "DRW":
                bad("removal is only meaningful in mode DRW")
            if dev not in REMOVABLE or variant not in REMOVAL_VARIANTS or dev not in self.devices:
                bad(f"removal must be '<watch|earbuds>:<table|stop>' of a simulated device, got {self.removal!r}")
        if self.mode == "DRW" and not any(d in self.devices for d in REMOVABLE):
            bad("DRW needs a watch or earbuds to remove")
        if self.area_m is not None and self.area_m < 16.0:
            bad(f"area_m must be at least 16 m, got {self.area_m}")
        if self.corridor_m is not None and not 1.0 <= self.corridor_m <= 20.0:
            bad(f"corridor_m must be within 1 … 20 m, got {self.corridor_m}")
        if not 0.0 <= self.speed_variation <= 0.3:
            bad(f"speed_variation must be within 0 … 0.3, got {self.speed_variation}")

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["devices"] = list(self.devices)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> WalkConfig:
        d = dict(d)
        known = {f.name for f in fields(cls)}
        extra = set(d) - known
        if extra:
            raise ConfigError(f"unknown walk config keys {sorted(extra)}")
        if "subject" in d and isinstance(d["subject"], dict):
            d["subject"] = SubjectParams(**d["subject"])
        if "devices" in d:
            d["devices"] = tuple(d["devices"])
        return cls(**d)

    def replace(self, **changes) -> WalkConfig:
        return replace(self, **changes)
