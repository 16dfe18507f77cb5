"""The live tracker against offline `wearnav track` (issue 23 §1, online inference).

A simulated Sensor Logger export (phone, watch, earbuds, fixes; its walk's truth regenerated from
the same seed) is replayed message by message into a :class:`SessionBuffer` as Sensor Logger would
push it (:func:`wearnav.live.replay.build`, 0.2-s batches), the tracker updating after each message;
then ``wearnav track`` runs on the export. Measured numbers are printed (``pytest -s``).
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd
import pytest

from wearnav.core import geo
from wearnav.importers.sensorlogger_export import ORIGIN, T0_NS, simulated_export, time_origin
from wearnav.live.bench import walker_export
from wearnav.live.buffer import SessionBuffer
from wearnav.live.replay import build
from wearnav.live.tracker import LiveTracker
from wearnav.simulate import WalkConfig, simulate_recording
from wearnav.track import odometry, track

WALK_S = 180.0  # longer than CONTEXT_S + FRAME_LAG_S (150 s): the middle windows see only part of the walk
SEED = 3


@pytest.fixture(scope="module")
def export(tmp_path_factory):
    root = tmp_path_factory.mktemp("live_tracker")
    simulated_export(root / "export", seed=SEED, duration_s=WALK_S)
    return root


@pytest.fixture(scope="module")
def short_export(tmp_path_factory):
    root = tmp_path_factory.mktemp("live_tracker_short")
    simulated_export(root / "export", seed=SEED, duration_s=90.0)
    return root


def replay_into(tracker: LiveTracker, folder, messages: int | None = None) -> dict:
    """Every message of the export (the first ``messages``) into a SessionBuffer, an update after
    each; then the final update. Returns the buffer, the replay, per-update wall times (s), process
    CPU (s)."""
    rp = build(folder, batch_s=0.2, start_ns=time.time_ns())
    buf = SessionBuffer(rp.session_id, rp.platform, rp.standardised)
    walls, cpu0 = [], time.process_time()
    for msg in rp.messages[:messages]:
        buf.add(msg["payload"])
        tic = time.perf_counter()
        tracker.update(buf)
        walls.append(time.perf_counter() - tic)
    tracker.update(buf, final=True)
    return {"buf": buf, "replay": rp, "walls": np.asarray(walls), "cpu_s": time.process_time() - cpu0}


def offline_times(run: dict, table: pd.DataFrame) -> np.ndarray:
    """The offline path's times on the session's clock (both are s since their own first sample)."""
    t0_offline = table["unix_time"].iloc[0] - table["t"].iloc[0]
    offset_s = (run["buf"].t0_unix_ns - run["replay"].shift_ns) * 1e-9 - t0_offline
    return table["t"].to_numpy() - offset_s


def test_phone_model_live_odometry_is_tracks_to_round_off(short_export):
    """One device: the preprocessing is local in time, so every window sees its offline input; the
    live path (un-fused) is track's at every path sample to 1e-4 m, and fused (the fixed-lag
    smoother's window outlasts this walk: the same problem as track's batch smoother) to 1 cm."""
    tr = LiveTracker(model="phone", activity_model=None)
    run = replay_into(tr, short_export / "export")
    track(short_export / "export", "phone", short_export / "track_phone")
    table = pd.read_csv(short_export / "track_phone" / "trajectory.csv")
    t, xy = np.asarray(tr.odo.t), np.asarray(tr.odo.xy)
    assert len(t) == len(table)
    assert np.abs(t - offline_times(run, table)).max() < 1e-6 + 5e-5  # the CSV keeps 4 decimals
    # track's own numbers at full precision, and as its CSV has them (rounded to 1e-4 m)
    rec = run["buf"].recording()
    *_, t_off, xy_off = odometry(tr.model, tr.cfg, rec)
    assert np.array_equal(t, t_off)
    gap = np.linalg.norm(xy - xy_off, axis=1)
    gap_csv = np.linalg.norm(xy - table[["x", "y"]].to_numpy(), axis=1)
    print(f"\nphone model, live vs offline odometry: max {gap.max():.2e} m (CSV: {gap_csv.max():.2e} m)")
    assert gap.max() < 1e-4 and gap_csv.max() < 1e-4 + 0.75e-4
    assert tr.origin == pytest.approx((rec.meta["origin_lat"], rec.meta["origin_lon"]), abs=1e-9)
    _, fused, _, anchor = tr.path()
    dev = np.linalg.norm(fused - table[["east", "north"]].to_numpy(), axis=1)
    print(f"phone model, fused live vs track: max {dev.max():.4f} m, p95 {np.percentile(dev, 95):.4f} m ({anchor})")
    assert anchor == "smooth-fixed-lag" and dev.max() < 0.01


def test_pdr_on_a_phone_only_session_is_tracks_to_round_off(short_export):
    """PDR on a phone-only session (its default where the shipped phone model did not measure better,
    wearnav.pretrained.phone_only_choice), whose layout lists all three devices: with
    only the phone present the common frame is the phone's own, so windows are final 1 s after them
    and aligned with ONE_DEVICE_CONTEXT_S, as for a one-device model (issue 37: it had waited
    FRAME_LAG_S, re-predicting a minute of windows at every update); the live odometry is still
    track's to round-off and the fused path within 1 cm of track's."""
    phone = walker_export(short_export / "export", "phone")
    tr = LiveTracker(model="pdr", activity_model=None)
    run = replay_into(tr, phone)
    assert str(tr.model_path) == "pdr" and len(tr.cfg.devices) == 3 and not tr._multi
    track(phone, "pdr", short_export / "track_pdr")
    table = pd.read_csv(short_export / "track_pdr" / "trajectory.csv")
    t, xy = np.asarray(tr.odo.t), np.asarray(tr.odo.xy)
    *_, t_off, xy_off = odometry(tr.model, tr.cfg, run["buf"].recording())
    assert np.array_equal(t, t_off) and len(t) == len(table)
    gap = np.linalg.norm(xy - xy_off, axis=1)
    _, fused, _, anchor = tr.path()
    dev = np.linalg.norm(fused - table[["east", "north"]].to_numpy(), axis=1)
    busy = np.asarray(tr.timings) * 1e3
    print(
        f"\nPDR, phone only: live vs offline odometry max {gap.max():.2e} m; fused vs track max {dev.max():.4f} m "
        f"({anchor}); updates p50 {np.median(busy):.0f} ms, p95 {np.percentile(busy, 95):.0f} ms; "
        f"CPU {run['cpu_s'] / float(t[-1] - t[0]):.3f} s per s of walk"
    )
    assert gap.max() < 1e-4 and anchor == "smooth-fixed-lag" and dev.max() < 0.01


def truth_on(run: dict, t: np.ndarray) -> np.ndarray:
    """The simulated walk's true east/north (m, the session's fix frame) at session times ``t``."""
    sim = simulate_recording(WalkConfig(mode="PVW", placement="MP", duration_s=WALK_S), seed=SEED)
    rec = run["buf"].recording()
    lat, lon = geo.local_to_latlon(sim.truth.pos[:, :2], *ORIGIN)
    en = geo.latlon_to_local(lat, lon, rec.meta["origin_lat"], rec.meta["origin_lon"])
    # export time = simulator time − its first sample; the session's t0 is the export's (both: earliest sample)
    ts = sim.truth.t - time_origin(sim) - (run["buf"].t0_unix_ns - run["replay"].shift_ns - T0_NS) * 1e-9
    return np.stack([np.interp(t, ts, en[:, 0]), np.interp(t, ts, en[:, 1])], axis=1)


@pytest.mark.slow
def test_three_devices_live_against_track_and_truth(export):
    """The shipped phone-watch-earbuds model: the same windows and path times as track, but each
    window's common frame (wearnav.preprocess.frames) is estimated from 90 s before it (CONTEXT_S) to 60 s
    after it (FRAME_LAG_S), not from the whole walk, so the live input differs slightly; measured here
    against track and against the truth. Also the update latency and CPU per second of walk (one
    thread, this machine), and the state the page gets: activity, fixes, 1-Hz points."""
    tr = LiveTracker(step_s=4.0)  # the windows and the final path do not depend on the step; fewer
    # re-predictions of the provisional minute keep this test short (the default's cost: `wearnav live bench`)
    run = replay_into(tr, export / "export")
    track(export / "export", None, export / "track_multi")
    table = pd.read_csv(export / "track_multi" / "trajectory.csv")
    t, xy = np.asarray(tr.odo.t), np.asarray(tr.odo.xy)
    assert tr.cfg.devices == ("phone", "watch", "earbuds") and len(t) == len(table)
    assert np.abs(t - offline_times(run, table)).max() < 1e-6 + 5e-5
    odo = np.linalg.norm(xy - table[["x", "y"]].to_numpy(), axis=1)
    _, fused, _, anchor = tr.path()
    dev = np.linalg.norm(fused - table[["east", "north"]].to_numpy(), axis=1)
    truth = truth_on(run, t)
    err_live, err_off = (np.linalg.norm(p - truth, axis=1) for p in (fused, table[["east", "north"]].to_numpy()))
    walk_s = float(t[-1] - t[0])
    busy, cpu = np.asarray(tr.timings) * 1e3, np.asarray(tr.cpu_timings) * 1e3
    print(
        f"\n3 devices, live vs track odometry (un-fused): max {odo.max():.2f} m, p95 {np.percentile(odo, 95):.2f} m"
        f"\n3 devices, fused live vs track: max {dev.max():.2f} m, p95 {np.percentile(dev, 95):.2f} m ({anchor})"
        f"\nerror vs truth, fused: live p50 {np.median(err_live):.2f} / p95 {np.percentile(err_live, 95):.2f} m, "
        f"track p50 {np.median(err_off):.2f} / p95 {np.percentile(err_off, 95):.2f} m"
        f"\nupdates that worked: {busy.size}, p50 {np.median(busy):.0f} ms, p95 {np.percentile(busy, 95):.0f} ms "
        f"(CPU p50 {np.median(cpu):.0f} ms, p95 {np.percentile(cpu, 95):.0f} ms); "
        f"every update (one per 0.2-s message) p95 {np.percentile(run['walls'], 95) * 1e3:.0f} ms; "
        f"CPU {run['cpu_s'] / walk_s:.3f} s per s of walk (buffer included)"
    )
    assert anchor == "smooth-fixed-lag" and dev.max() < 0.5  # the tolerance, at every path sample
    assert np.percentile(err_live, 95) < np.percentile(err_off, 95) + 1.0
    # the update's own cost (this process's CPU), not its wall time: under a shared machine's load (CI runs two
    # test workers on two cores beside other processes) the wall time says more about the load than the update
    assert np.percentile(cpu, 95) < 1000 and run["cpu_s"] / walk_s < 0.5
    state = tr.state()
    assert state["activity"]["label"] in [*tr.classifier[2], "unknown"]  # unknown: the model is unsure (issue 35)
    assert len(state["fixes"]) == len(run["buf"].recording().fixes)
    assert state["final_t_s"] == pytest.approx(t[-1], abs=1e-3)  # after the final update nothing is provisional
    step = int(round(tr.cfg.rate))
    assert [p[0] for p in state["path"]] == pytest.approx(
        np.append(t[::step], t[-1]) if (len(t) - 1) % step else t[::step], abs=6e-4
    )


def test_live_page_state_carries_a_users_floor_plan(short_export, tmp_path):
    """`wearnav live --map PLAN`: once the session has its origin (first fix), the page's state holds the
    plan's walkable polygons in the session's own frame, where its path is (issue 36)."""
    import json

    lat, lon = geo.local_to_latlon(
        np.array([[-400.0, -400.0], [400.0, -400.0], [400.0, 400.0], [-400.0, 400.0]]), *ORIGIN
    )
    ring = np.stack([lon, lat], 1).tolist()
    plan = tmp_path / "plan.geojson"
    plan.write_text(
        json.dumps(
            {
                "type": "FeatureCollection",
                "features": [
                    {
                        "type": "Feature",
                        "properties": {"kind": "walkable"},
                        "geometry": {"type": "Polygon", "coordinates": [ring + ring[:1]]},
                    }
                ],
            }
        )
    )
    phone = walker_export(short_export / "export", "phone")
    tr = LiveTracker(activity_model=None, plan=plan)
    replay_into(tr, phone)
    st = tr.state()
    assert st["origin"] is not None and len(st["plan"]) == 1
    outer = np.asarray(st["plan"][0][0][0])
    path = np.asarray([p[1:3] for p in st["path"]])
    lo, hi = outer.min(axis=0), outer.max(axis=0)
    assert np.all((path >= lo) & (path <= hi))  # the path lies inside the 800-m square drawn about the walk
    assert 790 < hi[0] - lo[0] < 810
    assert LiveTracker(activity_model=None).state()["plan"] == []


@pytest.mark.slow
def test_a_heading_frame_model_live_is_tracks_to_round_off(short_export, tmp_path, monkeypatch, capsys):
    """Issue 34's heading frame through `wearnav train --heading-frame` (a phone-only model, one
    epoch on the tiny simulator), then live against offline: each window turned by the phone's own
    heading and its velocity turned back the same way in both, so the live path is track's to 1e-4 m
    (the turn itself is checked in test_preprocess_windows)."""
    from conftest import run_cli

    data, run = tmp_path / "sim", tmp_path / "run"
    assert run_cli(monkeypatch, capsys, "simulate", "--preset", "tiny", "--out", str(data))[0] == 0
    code, out, err = run_cli(
        monkeypatch, capsys, "train", "ronin", "--data", str(data), "--out", str(run), "--devices", "phone",
        "--epochs", "1", "--heading-frame", "--no-evaluate",
    )  # fmt: skip
    assert code == 0, err
    tr = LiveTracker(model=str(run), activity_model=None)
    assert tr.cfg is None or tr.cfg.heading_frame
    live = replay_into(tr, short_export / "export")
    assert tr.cfg is not None and tr.cfg.heading_frame
    rec = live["buf"].recording()
    *_, t_off, xy_off = odometry(tr.model, tr.cfg, rec)
    t, xy = np.asarray(tr.odo.t), np.asarray(tr.odo.xy)
    assert np.array_equal(t, t_off)
    gap = np.linalg.norm(xy - xy_off, axis=1)
    print(f"\nheading-frame model, live vs offline odometry: max {gap.max():.2e} m over {len(t)} samples")
    assert gap.max() < 1e-4 and np.ptp(xy_off, axis=0).max() > 1.0  # a path that moved, the same live


def test_preload_loads_what_the_first_sessions_ask_for(short_export, tmp_path, caplog):
    """SharedModels.preload loads the phone-only and three-device odometry models and the activity
    classifier before any session; the sessions then get those very objects (nothing loaded twice).
    A model that cannot be loaded is a warning there, left to the session to report."""
    from wearnav import pretrained
    from wearnav.live.models import SharedModels

    models = SharedModels("cpu")
    models.preload()
    keys = set(models._loaded)
    phone = (str(pretrained.model_path(None, "odometry", ("phone",))), "odometry")
    three = (str(pretrained.model_path(None, "odometry", ("phone", "watch", "earbuds"))), "odometry")
    assert {phone, three, (str(pretrained.model_path("activity", "classify")), "classify")} <= keys
    loaded = models._loaded[three][0]
    tracker = LiveTracker(models=models)
    replay_into(tracker, short_export / "export", messages=50)  # the models are taken at the first update
    assert tracker.model is loaded and set(models._loaded) == keys

    broken = SharedModels("cpu")
    with caplog.at_level("WARNING", logger="wearnav.live"):
        broken.preload(model=tmp_path / "no-such-model", activity_model=None)
    assert "preloading" in caplog.text and not broken._loaded


def test_model_device_is_checked_and_cpu_is_kept():
    """`--model-device`: cpu (and no choice: the default) stays on the CPU, auto picks CUDA only where
    there is one, anything else (or cuda without a GPU) is one clear error before a model loads."""
    import torch

    from wearnav.errors import ConfigError
    from wearnav.live.bench import models_on
    from wearnav.live.models import SharedModels

    assert SharedModels("cpu").device.type == "cpu" and models_on("cpu") == "cpu"
    assert SharedModels().device.type == "cpu" and models_on() == "cpu"
    assert SharedModels("auto").device.type == ("cuda" if torch.cuda.is_available() else "cpu")
    with pytest.raises(ConfigError, match="auto, cpu or cuda"):
        SharedModels("tpu")
    if not torch.cuda.is_available():
        with pytest.raises(ConfigError, match="no CUDA device"):
            SharedModels("cuda")
