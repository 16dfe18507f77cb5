"""A small multi-device Recording from simple physics, for tests that need realistic signals.

A walker follows a curving path (speed changes at mid-time, so two activity labels); the phone is
held tilted in front, the watch swings with the arm, the earbuds nod with the head and are taken
off and laid flat for a while (``worn`` False). Each device's orientation R(t) (world←device) is
an analytic function of time, so the gyroscope is the exact body rate of R and the accelerometer
is Rᵀ(a_world + g·ẑ): quaternions, gyro and accelerometer agree with each other, as a real
device's fused orientation does. Stand-in until :mod:`wearnav.simulate` exists.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from wearnav.recording import STANDARD_GRAVITY, DeviceStream, Fixes, Recording, Trajectory

G = STANDARD_GRAVITY
RATES = {"phone": 100.0, "watch": 50.0, "earbuds": 25.0}
OFF_EARS = (24.0, 30.0)  # earbuds out of the ears (laid flat) during this interval


def _smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def _speed(t, duration):
    mid = duration / 2
    s = 1.1 + 0.5 * 0.5 * (1 + np.tanh((t - mid) / 1.5))
    ds = 0.5 * 0.5 / 1.5 / np.cosh((t - mid) / 1.5) ** 2
    return s, ds


def _heading(t):
    return 0.3 + 0.08 * t + 0.4 * np.sin(0.15 * t), 0.08 + 0.06 * np.cos(0.15 * t)


def _position(t, duration):
    """Position by integrating velocity on a fine grid (heading and speed are analytic)."""
    fine = np.linspace(0, duration, int(duration * 200) + 1)
    s, _ = _speed(fine, duration)
    psi, _ = _heading(fine)
    v = np.stack([s * np.cos(psi), s * np.sin(psi)], 1)
    pos = np.concatenate([[[0.0, 0.0]], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(fine)[:, None], 0)])
    return np.stack([np.interp(t, fine, pos[:, k]) for k in range(2)], 1)


def _acc_world(t, duration):
    s, ds = _speed(t, duration)
    psi, dpsi = _heading(t)
    step = 2 * np.pi * 1.8
    ax = ds * np.cos(psi) - s * dpsi * np.sin(psi)
    ay = ds * np.sin(psi) + s * dpsi * np.cos(psi)
    az = -0.04 * step**2 * np.sin(step * t)  # vertical bounce of the gait
    return np.stack([ax, ay, az], 1)


def _rotation(dev: str, t, duration) -> Rotation:
    worn_only = dev == "earbuds_worn"
    dev = "earbuds" if worn_only else dev
    psi, _ = _heading(t)
    step = 2 * np.pi * 0.9  # arm swing / head nod at stride frequency
    if dev == "phone":
        tilt = np.stack([np.deg2rad(40) + 0.08 * np.sin(2 * step * t), 0.1 * np.sin(step * t)], 1)
        yaw_off = 0.2
    elif dev == "watch":
        tilt = np.stack([np.deg2rad(70) + 0.5 * np.sin(step * t), np.deg2rad(20) + 0.3 * np.cos(step * t)], 1)
        yaw_off = -1.2
    else:
        tilt = np.stack([0.1 * np.sin(2 * step * t), 0.05 * np.cos(step * t)], 1)
        yaw_off = 1.0
    r = Rotation.from_euler("ZXY", np.column_stack([psi + yaw_off, tilt]))
    if dev == "earbuds" and not worn_only:  # taken off: blend smoothly to lying flat, then back
        a, b = OFF_EARS
        blend = _smoothstep((t - a) / 1.0) * (1 - _smoothstep((t - b + 1.0) / 1.0))
        # lying on its side: 70° from how it sat in the ear when taken out
        rest = _rotation("earbuds_worn", np.array([a]), duration) * Rotation.from_euler("X", 1.2)
        rel = (r.inv() * rest).as_rotvec()
        r = r * Rotation.from_rotvec(blend[:, None] * rel)
    return r


def synthetic_recording(
    name: str = "synthetic",
    duration: float = 40.0,
    seed: int = 0,
    devices=("phone", "watch", "earbuds"),
    fixes: bool = True,
    truth: bool = True,
    labels: bool = True,
    gyro: bool = True,
) -> Recording:
    rng = np.random.default_rng(seed)
    streams = {}
    for dev in devices:
        rate = RATES.get(dev, 50.0)
        t = np.arange(0, duration, 1 / rate) + 0.003 * (list(RATES).index(dev) if dev in RATES else 0)
        r = _rotation(dev, t, duration)
        h = 1e-4
        r_minus, r_plus = _rotation(dev, t - h, duration), _rotation(dev, t + h, duration)
        omega = (r_minus.inv() * r_plus).as_rotvec() / (2 * h)
        a_world = _acc_world(t, duration)
        worn = np.ones(len(t), bool)
        if dev == "earbuds":
            a, b = OFF_EARS
            worn = ~((t >= a) & (t < b))
            a_world[~worn] = 0.0
        acc = r.inv().apply(a_world + [0, 0, G]) + 0.05 * rng.standard_normal((len(t), 3))
        q = r.as_quat()[:, [3, 0, 1, 2]]
        streams[dev] = DeviceStream(
            t=t,
            acc=acc,
            gyro=omega + 0.005 * rng.standard_normal((len(t), 3)) if gyro else None,
            quat=q,
            worn=worn if dev == "earbuds" else None,
        )
    tt = np.arange(0, duration, 0.1)
    tr = Trajectory(tt, _position(tt, duration)) if truth else None
    fx = None
    if fixes:
        tf = np.arange(0.5, duration, 1.0)
        acc_m = 3.0 + 4.0 * rng.random(len(tf))
        noise = acc_m[:, None] / 2 * rng.standard_normal((len(tf), 2))
        fx = Fixes(tf, _position(tf, duration) + noise, acc_m)
    rows = []
    if labels:
        mid = duration / 2
        rows = [(0.0, mid, "activity", "walk_slow"), (mid, duration, "activity", "walk_fast")]
        if "earbuds" in devices and duration > OFF_EARS[1]:
            rows += [
                (0.0, OFF_EARS[0], "earbuds", "in_ears"),
                (*OFF_EARS, "earbuds", "on_table"),
                (OFF_EARS[1], duration, "earbuds", "in_ears"),
            ]
    return Recording(
        name=name,
        devices=streams,
        truth=tr,
        fixes=fx,
        labels=rows,
        meta={"subject": "s1", "mode": "walk", "placement": "hand", "source": "synthetic"},
    )
