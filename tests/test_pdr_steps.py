"""PDR's step detector across walkers and phones (issue 56 §6): a gentle walker's steps, half as
strong as another's, are still counted; a still phone counts none; a vigorous walk counts exactly
what the fixed 0.6 m/s² threshold counted before (the calibrations made with it keep their
meaning)."""

from __future__ import annotations

import numpy as np
import pytest

from wearnav.models.pdr import PDR
from wearnav.preprocess import PreprocessConfig, clock, stream_to_clock
from wearnav.recording import DeviceStream

RATE_HZ, WINDOW, STRIDE = 25.0, 100, 10  # the shipped phone model's windows (4 s, every 0.4 s)
G = 9.81


def windows_of(s: DeviceStream, mask_from: np.ndarray | None = None) -> np.ndarray:
    """The stream's acceleration on a 25 Hz clock (low-passed, as `track` preprocesses it), cut
    into (N, WINDOW, 3) windows every STRIDE samples."""
    t = clock(s.t[0], s.t[-1], RATE_HZ)
    x, mask = stream_to_clock(s, t, PreprocessConfig(rate=RATE_HZ, devices=("phone",), frame="device"))
    starts = [k for k in range(0, len(t) - WINDOW + 1, STRIDE) if mask[k : k + WINDOW].all()]
    return np.stack([x[k : k + WINDOW, :3] for k in starts]).astype(np.float64)


def vertical_bandpassed(acc: np.ndarray, pdr: PDR) -> np.ndarray:
    """(N, L) band-passed acceleration along each window's mean (gravity) direction."""
    g = acc.mean(axis=1, keepdims=True)
    vert = np.sum(acc * g / np.linalg.norm(g, axis=2, keepdims=True), axis=2)
    return pdr.bandpass(vert[..., None])[..., 0]


def total_steps(acc: np.ndarray, scale: float = 1.0) -> float:
    """Steps counted over windows that tile the recording every STRIDE samples, with the motion
    (everything but gravity, which the band-pass removes) scaled by ``scale``."""
    pdr = PDR(n_devices=1, window=WINDOW, rate=RATE_HZ)
    _, frac = pdr.steps(scale * vertical_bandpassed(acc, pdr))
    return float(np.sum(frac) / ((WINDOW - 1) / RATE_HZ) * STRIDE / RATE_HZ)


def gentle_walk(amp: float, cadence_hz: float, seconds: float = 60.0, seed: int = 0) -> DeviceStream:
    """A 100 Hz phone lying flat in a gentle walker's hand: a vertical bounce of ``amp`` m/s² at the
    step frequency (with a cadence wander of a few per cent), a fore-aft surge, and 0.05 m/s² of
    sensor noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(0, seconds, 0.01)
    phase = 2 * np.pi * np.cumsum(cadence_hz * (1 + 0.03 * np.sin(2 * np.pi * t / 7.0))) * 0.01
    acc = rng.normal(0.0, 0.05, (len(t), 3))
    acc[:, 2] += G + amp * np.cos(phase)
    acc[:, 1] += 0.5 * amp * np.sin(phase)
    return DeviceStream(t=t, acc=acc)


@pytest.mark.parametrize("cadence_hz", [1.6, 1.9])
def test_a_walk_half_as_strong_keeps_its_steps(cadence_hz):
    """Today's fixed 0.6 m/s² threshold counts every step at a 1.2 m/s² bounce and none at 0.6."""
    acc = windows_of(gentle_walk(1.2, cadence_hz))
    full, half = total_steps(acc), total_steps(acc, 0.5)
    assert full == pytest.approx(cadence_hz * 56, rel=0.1)  # 60 s, less half a window at each end
    assert half == pytest.approx(full, rel=0.1)


def test_a_real_hand_held_walk_half_as_strong_keeps_its_steps(shared_data):
    """IPIN 2023's first training trial (a phone in the hand): over the windows where its surveyed
    reference points say the walker moves (faster than 0.6 m/s over the window; the truth only
    picks the windows), the steps counted with the motion halved stay within 10 % of those at full
    strength (measured 4 % fewer; today 64 % fewer)."""
    from wearnav.importers import ipin2023

    rec = next(iter(ipin2023.read(shared_data / "ipin2023_track3", limit=1)))
    s, truth = rec.devices["phone"], rec.truth
    assert truth is not None
    acc = windows_of(s)
    t_c = s.t[0] + (np.arange(len(acc)) * STRIDE + WINDOW / 2) / RATE_HZ
    half_s = (WINDOW - 1) / RATE_HZ / 2
    ends = [np.stack([np.interp(t_c + d, truth.t, truth.pos[:, i]) for i in range(2)], 1) for d in (-half_s, half_s)]
    speed = np.linalg.norm(ends[1] - ends[0], axis=1) / (2 * half_s)
    walking = (speed > 0.6) & (t_c - half_s >= truth.t[0]) & (t_c + half_s <= truth.t[-1])
    full, half = total_steps(acc[walking]), total_steps(acc[walking], 0.5)
    assert walking.sum() > 100 and full > 150
    assert half == pytest.approx(full, rel=0.1)


def test_a_gentle_walkers_steps_against_the_truth(shared_data):
    """Oxford's step counter (truth by a separate device): user 2's hand-held walk with its motion
    scaled to a gentle walker's (a tenth: the band-passed peaks near 0.35 m/s², as on the Android
    walk of issue 56) and the phone's own 0.05 m/s² noise added back: within 10 % of the truth."""
    from wearnav.importers import oxford_steps

    path = shared_data / "oxford_step_counter" / "validation" / "user2_hand_1506421987098.csv.xz"
    (rec,) = oxford_steps.read(path)
    s = rec.devices["phone"]
    acc = windows_of(s)
    steps = rec.labels[rec.labels["kind"] == "step"]["start"].to_numpy()
    t_c = s.t[0] + (np.arange(len(acc)) * STRIDE + WINDOW / 2) / RATE_HZ
    lo, hi = t_c[0] - STRIDE / RATE_HZ / 2, t_c[-1] + STRIDE / RATE_HZ / 2
    true = int(np.sum((steps >= lo) & (steps < hi)))
    assert total_steps(acc) == pytest.approx(true, rel=0.05)
    g = acc.mean(axis=1, keepdims=True)
    gentle = g + 0.1 * (acc - g) + np.random.default_rng(0).normal(0.0, 0.05, acc.shape)
    assert total_steps(gentle) == pytest.approx(true, rel=0.1)


def test_a_still_phone_counts_no_steps(shared_data):
    """UCI HAPT's first recording (a phone at the waist): its standing and sitting minutes count
    (almost) no steps; so does a synthetic phone lying still with 0.05 m/s² noise. (Its second
    lying interval, 117–136 s, holds a regular 1.8 Hz bounce of 1–1.9 m/s², counted as 53 steps by
    the fixed threshold as by this one: a label that is not what the phone did.)"""
    from wearnav.importers import uci_hapt

    (rec,) = uci_hapt.read(shared_data / "uci_hapt", limit=1)
    acts = rec.labels[rec.labels["kind"] == "activity"]
    s = rec.devices["phone"]
    seconds, steps = 0.0, 0.0
    for a, b in acts[acts["value"].isin(["STANDING", "SITTING"])][["start", "end"]].to_numpy():
        keep = (s.t >= a) & (s.t <= b)
        if (b - a) * RATE_HZ > WINDOW + STRIDE:
            piece = DeviceStream(t=s.t[keep], acc=s.acc[keep])
            seconds += b - a
            steps += total_steps(windows_of(piece))
    assert seconds > 60 and steps / seconds * 60 < 1.0  # steps per minute
    still = gentle_walk(0.0, 1.8)
    assert total_steps(windows_of(still)) == 0.0


def test_a_vigorous_walk_counts_as_before():
    """Where the band-passed bounce is well above 0.6 m/s² (every window's amplitude at least
    0.6 / PEAK_FRACTION), the steps are exactly those of the fixed 0.6 m/s² threshold."""
    pdr = PDR(n_devices=1, window=WINDOW, rate=RATE_HZ)
    fixed = PDR(n_devices=1, window=WINDOW, rate=RATE_HZ, peak_floor=0.6)
    acc = windows_of(gentle_walk(2.5, 1.8, seed=3))
    x = vertical_bandpassed(acc, pdr)
    assert np.quantile(np.abs(x), 0.9, axis=1).min() > 0.6 / pdr.peak_fraction
    n, frac = pdr.steps(x)
    n0, frac0 = fixed.steps(x)
    assert np.array_equal(n, n0) and np.array_equal(frac, frac0)
