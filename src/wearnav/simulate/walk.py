"""One simulated walk: scenario → route and gait → body → device poses → IMU streams, truth,
location fixes, labels and metadata, assembled into a :class:`~wearnav.recording.Recording`.

:func:`simulate_walk` also returns the noise-free kinematics of every device at its sample times
(:class:`~wearnav.simulate.imu.TrueImu`), which the tests use to check the physics.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation
from shapely.geometry import LineString

from wearnav.core.rotations import matrix_to_wxyz
from wearnav.plans import plan_from_geometry
from wearnav.recording import DeviceStream, FloorPlan, Recording, Trajectory
from wearnav.simulate.body import Body
from wearnav.simulate.config import REMOVABLE, SCENES, WalkConfig
from wearnav.simulate.fixes import FixNoise, simulate_fixes
from wearnav.simulate.imu import IMU_SPECS, ImuErrors, TrueImu, antialiased, sample_times, true_imu
from wearnav.simulate.path import BaseMotion
from wearnav.simulate.placement import Earbuds, Phone, PosePath, Removed, Watch
from wearnav.simulate.scenario import WALK_RAMP_S, Scenario, make_scenario

SIMULATOR_VERSION = 3  # 2: calibrated against real walking (docs/realism.md); 3: speed in the gait (cadence, bounce), receiver-filter fix error
_STREAMS = (
    "scenario",
    "path",
    "body",
    "phone",
    "watch",
    "earbuds",
    "removal",
    "area",
    "imu_phone",
    "imu_watch",
    "imu_earbuds",
    "fixes",
)


@dataclass
class SimulatedWalk:
    """A simulated recording plus the ground truth behind it."""

    config: WalkConfig
    seed: int
    recording: Recording
    devices: dict[str, TrueImu]  # noise-free kinematics at each stream's sample times
    poses: dict[str, PosePath]  # device pose functions, evaluable at any time
    body: Body
    scenario: Scenario
    cadence_hz: float  # mean true step frequency while walking


def as_seed(seed) -> int:
    """An int seed from an int, a SeedSequence or a Generator (which is advanced by one draw)."""
    if isinstance(seed, np.random.Generator):
        return int(seed.integers(0, 2**32))
    if isinstance(seed, np.random.SeedSequence):
        return int(seed.generate_state(1)[0])
    return int(seed)


def simulate_walk(cfg: WalkConfig, seed=0) -> SimulatedWalk:
    seed = as_seed(seed)
    rngs = {k: np.random.default_rng(s) for k, s in zip(_STREAMS, np.random.SeedSequence(seed).spawn(len(_STREAMS)))}
    T = cfg.duration_s
    area = cfg.area_m if cfg.area_m is not None else float(rngs["area"].uniform(*SCENES[cfg.scene]))
    scenario = make_scenario(cfg, rngs["scenario"])
    base = BaseMotion(cfg.subject, scenario.bouts, T, area, cfg.speed_variation, rngs["path"], WALK_RAMP_S)
    body = Body(cfg.subject, scenario, base, rngs["body"])

    poses: dict[str, PosePath] = {}
    for dev in cfg.devices:
        if dev == "phone":
            poses[dev] = Phone(body, scenario, rngs["phone"])
        elif dev == "watch":
            poses[dev] = Watch(body, rngs["watch"])
        else:
            poses[dev] = Earbuds(body, rngs["earbuds"])
    rem = scenario.removal
    if rem is not None:
        poses[rem.device] = Removed(poses[rem.device], rem, body, rngs["removal"])

    streams, truths, dev_meta = {}, {}, {}
    for dev in cfg.devices:
        spec = IMU_SPECS[dev]
        rng = rngs[f"imu_{dev}"]
        t_start = float(rng.uniform(*spec.start_delay_s))
        t_end = T - float(rng.uniform(0.0, 0.3))
        if rem is not None and rem.device == dev and rem.variant == "stop":
            t_end = rem.start
        t = sample_times(spec, rng, t_start, t_end)
        tru = true_imu(poses[dev].pose, t)
        if cfg.imu_noise:
            err = ImuErrors.draw(spec, rng, t_start, T)
            acc, gyro, quat = err.measure(antialiased(poses[dev].pose, tru, spec), rng)
            dev_meta[dev] = {"rate_hz": spec.rate_hz, "imu_noise": True, **err.summary()}
        else:
            acc, gyro, quat = tru.specific_force, tru.omega, matrix_to_wxyz(tru.R)
            dev_meta[dev] = {"rate_hz": spec.rate_hz, "imu_noise": False, "quat_yaw_offset_deg": 0.0}
        worn = poses[dev].worn(t) if dev in REMOVABLE else None
        streams[dev] = DeviceStream(t=t, acc=acc, gyro=gyro, quat=quat, worn=worn)
        truths[dev] = tru

    t_truth = np.arange(0.0, T, 1.0 / cfg.truth_rate_hz)
    st = body.evaluate(t_truth)
    truth = Trajectory(t_truth, st.chest, matrix_to_wxyz(st.R_torso))

    noise = FixNoise.from_level(cfg.noise_level, cfg.fix_correlation_s)
    t_fix = np.arange(1.0, T - 0.5, 1.0 / cfg.fix_rate_hz)
    fixes = simulate_fixes(t_fix, body.evaluate(t_fix).chest[:, :2], noise, rngs["fixes"])

    walking = base(t_truth)[:, BaseMotion.ENV] > 0.5
    step = np.linalg.norm(np.diff(truth.pos[:, :2], axis=0), axis=1)
    dur_walk = walking.sum() / cfg.truth_rate_hz
    meta = {
        "subject": cfg.subject.name,
        "mode": cfg.mode,
        "placement": cfg.placement,
        "scene": cfg.scene,
        "source": "simulator",
        "licence": "generated by the wearnav simulator; no restrictions",
        "seed": seed,
        "noise_level": cfg.noise_level,
        "cadence_hz": round(base.mean_cadence_hz, 4),
        "speed_mps": round(float(step[walking[1:]].sum() / max(dur_walk, 1e-9)), 4),
        "distance_m": round(float(step.sum()), 2),
        "area_m": round(area, 2),
        "duration_s": T,
        "phone_placements": sorted({h.placement for h in scenario.holds}),
        "removed_device": rem.device if rem else None,
        "removal_variant": rem.variant if rem else None,
        "devices": dev_meta,
        "fix_noise": {
            "median_label_noise_m": noise.median_label_noise_m,
            "sigma_m": round(noise.sigma, 4),
            "correlation_s": noise.correlation_s,
        },
        "truth": "chest point (harness) position; quat = torso orientation world<-torso (x forward, y left, z up)",
        "config": cfg.to_dict(),
        "simulator_version": SIMULATOR_VERSION,
    }
    if "phone" in poses:
        meta["phone_hand"] = getattr(poses["phone"], "hand", None)
    if "phone" in poses and (bag := getattr(poses["phone"], "bag", None)) is not None:
        meta.update(bag.meta)
    plans = [] if cfg.corridor_m is None else [corridor_plan(cfg.name, truth.pos[:, :2], cfg.corridor_m)]
    if plans:
        meta["plan"] = plans[0].name
    rec = Recording(
        name=cfg.name,
        devices=streams,
        truth=truth,
        fixes=fixes,
        labels=scenario.label_rows(cfg.mode),
        meta=meta,
        plans=plans,
    )
    return SimulatedWalk(cfg, seed, rec, truths, poses, body, scenario, base.mean_cadence_hz)


# The route a corridor plan follows: the true path thinned to a point every CORRIDOR_STEP_M metres
# (a corridor's walls are straight over a step; the buffer rounds the corners).
CORRIDOR_STEP_M = 0.5


def corridor_plan(name: str, pos: np.ndarray, width_m: float) -> FloorPlan:
    """A floor plan of corridors ``width_m`` wide along the walker's route ``pos`` (N, 2) m: the
    walkable space of a building whose corridors this walk follows (issue 36: the map-aware path
    tested on synthetic walks with known truth). Where the route crosses itself the corridors join."""
    step = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(pos, axis=0), axis=1))]
    keep = np.unique(np.searchsorted(step, np.arange(0.0, step[-1], CORRIDOR_STEP_M)))
    route = pos[np.r_[keep, len(pos) - 1]]
    return plan_from_geometry(f"{name}_corridors", 0, LineString(route).buffer(width_m / 2.0).simplify(0.05))


def simulate_recording(cfg: WalkConfig, seed=0) -> Recording:
    """One simulated walk as a Recording; the same (cfg, seed) always gives identical arrays."""
    return simulate_walk(cfg, seed).recording


def reported_yaw_offset(rec: Recording, t: np.ndarray) -> dict[str, np.ndarray]:
    """For measuring frame alignments only: each device's yaw ψ(t) (rad, unwrapped) of its
    reported world frame relative to the truth frame at times ``t`` — the drawn offset plus the
    yaw walk, recovered by re-simulating the walk from ``meta`` (config and seed) and comparing the
    reported orientation with the true one (R_out · R_trueᵀ = Rz(ψ) · small tilt error)."""
    sw = simulate_walk(WalkConfig.from_dict(rec.meta["config"]), rec.meta["seed"])
    out = {}
    for dev, s in sw.recording.devices.items():
        R_true = sw.devices[dev].R
        R_out = Rotation.from_quat(s.quat, scalar_first=True).as_matrix()
        M = R_out @ np.swapaxes(R_true, -1, -2)
        psi = np.unwrap(np.arctan2(M[:, 1, 0], M[:, 0, 0]))
        out[dev] = np.interp(t, s.t, psi)
    return out
