"""What is compared: the device placements, their simulated walkers and real recordings.

:data:`GROUPS` pairs each simulated placement with the real recordings of the same placement;
:data:`CLAIMED` lists the statistics the calibrated simulator promises to match there.
:func:`simulate_realism_walks` makes the simulated side, :func:`open_real` imports (once) and
opens the real side.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wearnav.errors import WearnavError
from wearnav.recording import Recording

SIM_DURATION_S = 120.0  # per simulated walk; long enough for GNSS jumps to show per recording


@dataclass(frozen=True)
class RealSource:
    """Real recordings: dataset format, the device to read, which recordings (name regex)."""

    label: str
    fmt: str
    folder: str  # under the data root; imported from there
    device: str
    names: str = ".*"


@dataclass(frozen=True)
class Group:
    """One device and placement: the simulated hold and its real counterparts."""

    key: str
    title: str
    sim_device: str
    sim_hold: str
    real: tuple[RealSource, ...] = ()


# Calibration data: ILC2 site 1 floor F1 only, IPIN 2023 training trials 01 and 02 only. The
# odometry benchmarks must not evaluate on these (they are the simulator's calibration set).
ILC2_CALIBRATION = "site1/F1"
IPIN_CALIBRATION = r"IPIN2023_T3_TrainingTrial0[12]_"
GROUPS: tuple[Group, ...] = (
    Group(
        "phone_hand",
        "phone held in the hand in front of the body (texting)",
        "phone",
        "texting",
        (
            RealSource("ILC2 F1", "ilc2", f"ilc2_indoor_location/{ILC2_CALIBRATION}", "phone"),
            RealSource("IPIN T01-02", "ipin2023", "ipin2023_track3", "phone", IPIN_CALIBRATION),
            RealSource("Oxford hand", "oxford-steps", "oxford_step_counter", "phone", r"_hand_"),
        ),
    ),
    Group(
        "phone_front_pocket",
        "phone in a front trouser pocket",
        "phone",
        "front_pocket",
        (
            RealSource("MotionSense", "motionsense", "motionsense", "phone", r"_wlk_"),
            RealSource("UJI phone", "uji-phone-watch", "uji_phone_watch_har", "phone"),
            RealSource("Oxford frontpocket", "oxford-steps", "oxford_step_counter", "phone", r"_frontpocket_"),
        ),
    ),
    Group(
        "phone_back_pocket",
        "phone in a back trouser pocket",
        "phone",
        "back_pocket",
        (RealSource("Oxford backpocket", "oxford-steps", "oxford_step_counter", "phone", r"_backpocket_"),),
    ),
    Group(
        "phone_bag",
        "phone in a bag",
        "phone",
        "bag",
        (RealSource("Oxford bag", "oxford-steps", "oxford_step_counter", "phone", r"_bag_"),),
    ),
    Group(
        "watch",
        "watch on the wrist",
        "watch",
        "texting",
        (RealSource("UJI watch", "uji-phone-watch", "uji_phone_watch_har", "watch"),),
    ),
    Group("phone_swinging", "phone in the swinging hand", "phone", "swinging"),
    Group("earbuds", "earbuds (25 Hz)", "earbuds", "texting"),
)
FIX_REAL = RealSource("IPIN T01-02", "ipin2023", "ipin2023_track3", "phone", IPIN_CALIBRATION)

# Statistics the calibrated simulator claims to match: in band in this report and, re-checked by
# tests/test_realism.py, in band for fresh simulations (12 walkers × 40 s) over four seeds. The
# others marked "yes" in the tables are in band here but too close to an edge to promise.
CLAIMED = {
    "phone_hand": ("acc_std", "gyro_mean", "f_dom", "step_cv", "amp_cv", "hv_ratio", "band_0.3_1.2", "band_2.6_5"),
    "phone_front_pocket": ("acc_std", "gyro_mean", "f_dom", "cadence", "amp_cv", "band_5_8", "band_8_12.5"),
    # step_cv and band_0.3_1.2 were claimed too until the pelvis' fore-aft ripple got the inverted
    # pendulum's phase (forward acceleration leading the vertical, as ILC2's phones show); since
    # then they fall below the band in 2 of 4 seeds: recalibrating the arm swing is open work.
    "watch": ("acc_std", "f_dom", "cadence", "amp_cv"),
    "phone_bag": ("f_dom", "cadence", "step_reg", "step_cv"),
    "phone_back_pocket": ("f_dom", "cadence"),
}

# What the calibration (simulator version 2) set, against which statistics and recordings: one row
# per parameter (the page's table), then what is not calibrated.
CALIBRATION_COLUMNS = ("simulator parameter (src/wearnav/simulate/)", "calibrated against", "real recordings")
CALIBRATION_TABLE: tuple[tuple[str, str, str], ...] = (
    (
        "walker population cadence about 1.77 ± 0.07 steps/s, rising with speed as 1.77 · (v / 1.16)^0.22 "
        "(`config.sample_subject`)",
        "cadence, f_dom of every placement",
        "all sources above (real walkers: 1.66–1.88 steps/s)",
    ),
    (
        "step-to-step timing variability `step_time_cv` (path: cadence wander over one step)",
        "step-period CV",
        "ILC2 F1, IPIN T01-02, Oxford hand; UJI watch",
    ),
    (
        "step-to-step amplitude variability `step_amp_cv`, left/right asymmetry `step_asymmetry`",
        "step-amplitude CV, autocorr 1 step, power 0.3–1.2 Hz",
        "same",
    ),
    (
        "hand-held phone: step bob `hand_bob_deg`, forearm bounce and stride rise `hand_bounce_m`, heel-strike "
        "shock `hand_impact` (peak m/s², a 20 ms spike train, `body.impact_train`)",
        "\\|gyro\\|, \\|acc\\| std, horiz/vert, power by band",
        "ILC2 F1, IPIN T01-02, Oxford hand",
    ),
    (
        "watch: forearm roll at step frequency `wrist_wobble_deg`, arm swing 10–20°, the same heel-strike shock",
        "\\|gyro\\|, f_dom, autocorr 1 step, power by band",
        "UJI watch",
    ),
    (
        "front pocket: thigh heel-strike spike `leg_impact` (peak m/s², 16 ms, right heel only), irregular "
        "soft-tissue wobble `thigh_wobble_mm`, pocket 18 cm down the thigh, hip swing 22–30°",
        "\\|acc\\| std, \\|gyro\\|, autocorr 1 step, horiz/vert, power by band",
        "MotionSense, UJI phone, Oxford frontpocket",
    ),
    (
        "bag knocks on each heel strike (`BAG_JOLT_GAIN` × the hands' shock)",
        "\\|acc\\| std, power by band",
        "Oxford bag",
    ),
    (
        "GNSS multipath jumps (rate, size, hold), outages, accuracy growing with the offset (`fixes.FixNoise`)",
        "jumps per 100 fixes, outage lengths, reported accuracy / error",
        "IPIN T01-02 phone GNSS at POSI points",
    ),
)
CALIBRATION_NOTES = """\
Not calibrated here:

- **Earbuds**: no real earbud (or head-worn IMU) walking data is in ../shared/data. Assumed: the head
  motion of the body model as it was, and the IMU's own digital low-pass before its 25 Hz output, a
  zero-phase 15-tap FIR with an 8 Hz cut-off on the 100 Hz motion (`imu.antialiased`; about ODR/3, as
  MEMS IMUs configure their filter), so nothing above 12.5 Hz folds into the stream.
- **Phone swinging in the hand**: no real set here (Oxford's validation part has none).
- **Fix error size**: the simulator's fix error follows EasyTrack's three label-noise levels (median
  1-s displacement noise 21.6 / 27.6 / 33.5 cm, an Ornstein-Uhlenbeck error with τ = 120 s), open-sky
  phone GNSS; IPIN's indoor museum GNSS is larger. Keeping EasyTrack's levels wins: the error at the
  reference points is reported, not fitted.
- **Frozen fixes**: IPIN's indoor phone fixes often repeat the previous position or creep (see the
  fix-to-fix speed row: a quarter of its consecutive fixes do not move, while the walker does).
  Simulating that would put the walker's whole 1-s displacement into EasyTrack's label noise and break
  its calibrated levels, so the simulator's fixes keep following the walker.
- **Outages**: IPIN trials 01–02 hold no gap longer than 2.5 s in about 27 min, so the outage rate
  (one per 30 min, median 4 s) is an upper bound chosen to be consistent with that, not a fit.
- **Back pocket and bag** rest on Oxford's two recordings each (two walkers); their spectra are
  reported but not fitted beyond |acc| std.
"""


def simulate_realism_walks(hold: str, n: int, seed: int = 0, duration_s: float = 60.0) -> list[Recording]:
    """``n`` straight-walking (STW) recordings of ``n`` different walkers with the phone in
    ``hold``: the simulated side of the comparison. Subjects come from the simulator's own
    population model (:func:`~wearnav.simulate.sample_subject`), so its cadence spread counts."""
    from wearnav.simulate import WalkConfig, sample_subject, simulate_recording
    from wearnav.simulate.config import HOLDS_OF_PLACEMENT

    placement = next(p for p, holds in HOLDS_OF_PLACEMENT.items() if hold in holds and p != "MP")
    rng = np.random.default_rng(np.random.SeedSequence([seed, 11]))
    recs = []
    for i in range(n):
        subject = sample_subject(rng, f"r{i + 1}")
        cfg = WalkConfig(
            name=f"realism_{hold}_{i:02d}",
            subject=subject,
            mode="STW",
            placement=placement,
            phone_hold=hold,
            duration_s=duration_s,
            scene="medium",
            noise_level=("L1", "L2", "L3")[i % 3],
        )
        recs.append(simulate_recording(cfg, seed=int(rng.integers(0, 2**31))))
    return recs


def open_real(src: RealSource, data: Path, work: Path, limit: int | None):
    """The dataset of ``src`` (imported from ``data`` into ``work`` the first time) and the names
    of its recordings to use: those matching ``src.names``, at most ``limit`` spread evenly."""
    from wearnav.dataset import Dataset
    from wearnav.importers import import_dataset

    dest = work / re.sub(r"[^A-Za-z0-9]+", "_", src.fmt + "_" + src.folder).strip("_")
    if (dest / "manifest.csv").exists():
        ds = Dataset.open(dest)
    else:
        folder = data / src.folder
        if not folder.exists():
            raise WearnavError(f"{folder}: real data for the realism report not found")
        ds = import_dataset(src.fmt, folder, dest, progress=False)
    names = [n for n in ds.names if re.search(src.names, n)]
    if limit is not None and len(names) > limit:
        # evenly spread over the list (subjects, floors, trials), not the first few
        names = [names[int(i)] for i in np.linspace(0, len(names) - 1, limit)]
    return ds, names
