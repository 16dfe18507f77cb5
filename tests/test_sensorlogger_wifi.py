"""A user's own recording with Wi-Fi (issue 60 §3): Sensor Logger's ``WiFi.csv`` becomes the
recording's scans (:mod:`wearnav.importers.sensorlogger_radio`), and a radio map of a venue (its
positions about the venue's lat/lon origin) places a walk imported about its own first fix, its
positions converted into the recording's frame (:func:`wearnav.fuse.radiofixes.in_recordings_frame`).

The real-data test writes a real IPIN 2023 walk (phone IMU, GNSS fixes, Wi-Fi scans) as an Android
Sensor Logger export, imports it back, and compares what `track --radiomap` makes of it with what it
makes of the same walk imported from its IPIN log."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

from conftest import IPIN_HELD_OUT, IPIN_LOGS, IPIN_SURVEY
from wearnav.core import geo
from wearnav.errors import FormatError, ValidationError
from wearnav.fuse import radiobuild, radiofixes, radiomap
from wearnav.importers import ipin2023
from wearnav.importers.sensorlogger import read as read_sensorlogger
from wearnav.importers.sensorlogger import read_export
from wearnav.importers.sensorlogger_export import simulated_export, write_export, zip_export


@pytest.fixture(scope="module")
def export(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sl_wifi") / "export"
    simulated_export(folder, seed=2, duration_s=20.0)
    return folder


def wifi_rows(t0_ns: int) -> pd.DataFrame:
    """Three scans (their readings share a time; one before the motion files' start), an access point
    in upper case, and one row written twice."""
    rows = []
    for k, dt_s in enumerate((-0.5, 3.0, 7.0)):
        for ap in range(4):
            rows.append(
                {
                    "time": t0_ns + int(dt_s * 1e9),
                    "seconds_elapsed": dt_s,
                    "ssid": f"venue-{ap}",
                    "bssid": f"AA:BB:CC:00:00:{ap:02X}",
                    "frequency": 2412 + 5 * ap,
                    "level": -50 - 10 * ap - k,
                    "capabilities": "[WPA2-PSK-CCMP][ESS]",
                }
            )
    rows.insert(5, dict(rows[4]))  # the second scan's first reading written twice
    return pd.DataFrame(rows)


def test_wifi_csv_becomes_the_recordings_scans_on_its_clock(export, tmp_path):
    rec0 = read_export(export)
    assert rec0.wifi is None  # an export without WiFi.csv (an iPhone's) has none
    t0 = int(rec0.meta["t0_unix_ns"])
    folder = tmp_path / "with_wifi"
    folder.mkdir()
    for f in export.iterdir():
        (folder / f.name).write_bytes(f.read_bytes())
    wifi_rows(t0).to_csv(folder / "WiFi.csv", index=False)
    for rec in (read_export(folder), next(read_sensorlogger(zip_export(folder, tmp_path / "w.zip")))):
        w = rec.wifi
        assert w is not None and len(w.t) == 12  # 13 rows, the repeated one dropped
        assert rec.meta["dropped_duplicates"]["WiFi.csv"] == 1
        np.testing.assert_allclose(np.unique(w.t), [-0.5, 3.0, 7.0], atol=1e-9)  # the recording's clock
        assert list(w.bssid[:4]) == [f"aa:bb:cc:00:00:{ap:02x}" for ap in range(4)]  # lower case
        np.testing.assert_array_equal(w.freq_mhz[:4], [2412, 2417, 2422, 2427])
        np.testing.assert_array_equal(w.rssi_dbm[:4], [-50, -60, -70, -80])
        assert w.ssid[0] == "venue-0" and w.t_seen is None
        # the IMU and the fixes are what they were without the file
        np.testing.assert_array_equal(rec.devices["phone"].acc, rec0.devices["phone"].acc)
        np.testing.assert_array_equal(rec.fixes.pos, rec0.fixes.pos)


def test_barometer_csv_becomes_the_recordings_pressure(export, tmp_path):
    t0 = int(read_export(export).meta["t0_unix_ns"])
    folder = tmp_path / "with_barometer"
    folder.mkdir()
    for f in export.iterdir():
        (folder / f.name).write_bytes(f.read_bytes())
    times = t0 + np.array([0, 10**9, 10**9, 2 * 10**9])  # one time written twice
    rows = pd.DataFrame(
        {"time": times, "seconds_elapsed": 0.0, "relativeAltitude": 0.0, "pressure": [977.2, 977.3, 977.3, 977.6]}
    )
    rows.to_csv(folder / "Barometer.csv", index=False)
    rec = read_export(folder)
    np.testing.assert_allclose(rec.pressure.t, [0.0, 1.0, 2.0])
    np.testing.assert_allclose(rec.pressure.hpa, [977.2, 977.3, 977.6])
    assert rec.meta["dropped_duplicates"]["Barometer.csv"] == 1
    rows.assign(pressure=rows["pressure"] * 100).to_csv(folder / "Barometer.csv", index=False)  # Pa, not hPa
    with pytest.raises(FormatError, match=r"Barometer\.csv.*is not an air pressure"):
        read_export(folder)


@pytest.mark.parametrize(
    "name, header, attribute",
    [
        ("WiFi.csv", "time,seconds_elapsed,ssid,bssid,frequency,level,capabilities", "wifi"),
        ("Barometer.csv", "time,seconds_elapsed,relativeAltitude,pressure", "pressure"),
        ("Location.csv", None, "fixes"),  # indoors, not one fix: the app writes the header alone
    ],
)
def test_a_side_file_with_a_header_alone_reads_as_none(export, tmp_path, name, header, attribute):
    folder = tmp_path / "header_only"
    folder.mkdir()
    for f in export.iterdir():
        (folder / f.name).write_bytes(f.read_bytes())
    if header is None:  # the file's own header
        header = (folder / name).read_text().splitlines()[0]
    (folder / name).write_text(header + "\n")
    rec = read_export(folder)
    assert getattr(rec, attribute) is None and len(rec.devices["phone"].t) > 100
    (folder / "Gravity.csv").write_text((folder / "Gravity.csv").read_text().splitlines()[0] + "\n")
    with pytest.raises(FormatError, match="Gravity.csv: no data rows"):  # a motion file's rows are needed
        read_export(folder)


@pytest.mark.parametrize(
    "change, words",
    [
        (lambda df: df.drop(columns="level"), "missing columns ['level']"),
        (lambda df: df.assign(level=df["level"].astype(object).where(df.index != 3, "strong")), "NaN or infinite"),
        (lambda df: df.assign(level=df["level"].where(df.index != 3, 12)), "is not a received power"),
        (lambda df: df.assign(frequency=df["frequency"] / 1000.0), "is not a Wi-Fi channel"),
        (lambda df: df.assign(time=df["time"].iloc[::-1].to_numpy()), "timestamps go backwards"),
        (lambda df: df.assign(bssid=df["bssid"].where(df.index != 2, "")), "an empty bssid"),
    ],
)
def test_a_bad_wifi_csv_is_refused_in_one_line_naming_the_file(export, tmp_path, change, words):
    t0 = int(read_export(export).meta["t0_unix_ns"])
    folder = tmp_path / "bad"
    folder.mkdir()
    for f in export.iterdir():
        (folder / f.name).write_bytes(f.read_bytes())
    change(wifi_rows(t0)).to_csv(folder / "WiFi.csv", index=False)
    with pytest.raises((FormatError, ValidationError)) as err:
        read_export(folder)
    assert words in str(err.value) and "WiFi.csv" in str(err.value) and "\n" not in str(err.value)


@pytest.fixture(scope="module")
def venue(shared_data, tmp_path_factory):
    """A radio map of three IPIN walks over three floors (about the venue's origin) and a fourth,
    imported from its log and from it written as an Android Sensor Logger export."""
    recs = [ipin2023.read_log(shared_data / IPIN_LOGS / name) for name in [*IPIN_SURVEY, IPIN_HELD_OUT]]
    rmap = radiobuild.build(recs[:3], radiomap.RadioMapConfig(cv_folds=3))
    root = tmp_path_factory.mktemp("venue")
    write_export(recs[3], root / "export", platform="android", standardised=True)
    return rmap, recs[3], read_export(root / "export"), root


def _latlon(rec, xy: np.ndarray) -> np.ndarray:
    return np.stack(geo.local_to_latlon(xy, rec.meta["origin_lat"], rec.meta["origin_lon"]), axis=1)


@pytest.mark.real_data
def test_a_venues_map_places_a_users_export_as_it_places_the_walk_imported_from_its_log(venue):
    rmap, ipin, user, _ = venue
    assert rmap.origin == (ipin.meta["origin_lat"], ipin.meta["origin_lon"])
    # the export is about its first fix, the map about the venue's origin
    apart = geo.latlon_to_local([user.meta["origin_lat"]], [user.meta["origin_lon"]], *rmap.origin)
    print(f"\nthe export's origin is {np.linalg.norm(apart):.1f} m from the map's")
    assert np.linalg.norm(apart) > 5.0
    # the same scans (times shifted by the two imports' different zero)
    shift = user.wifi.t[0] - ipin.wifi.t[0]
    np.testing.assert_allclose(user.wifi.t - shift, ipin.wifi.t, atol=1e-6)
    assert list(user.wifi.bssid) == [b.lower() for b in ipin.wifi.bssid]
    np.testing.assert_array_equal(user.wifi.rssi_dbm, ipin.wifi.rssi_dbm)
    np.testing.assert_allclose(user.pressure.t - shift, ipin.pressure.t, atol=1e-6)
    np.testing.assert_array_equal(user.pressure.hpa, ipin.pressure.hpa)
    a, radio_a, info_a, warn_a = radiofixes.with_radio_fixes(ipin, rmap)
    b, radio_b, info_b, warn_b = radiofixes.with_radio_fixes(user, rmap)
    assert not warn_a and not warn_b and info_a["positions"] == info_b["positions"] > 50
    # the radio positions at one place on Earth, each in its recording's frame
    la, lb = _latlon(a, a.fixes.pos[radio_a, :2]), _latlon(b, b.fixes.pos[radio_b, :2])
    gap = geo.latlon_to_local(lb[:, 0], lb[:, 1], *la[0]) - geo.latlon_to_local(la[:, 0], la[:, 1], *la[0])
    assert np.abs(gap).max() < 1e-6


@pytest.mark.real_data
def test_track_with_a_venues_map_gives_a_users_export_the_path_of_the_imported_walk(venue):
    from wearnav.track import track

    rmap, ipin, user, root = venue
    folder = rmap.save(root / "map")
    paths, floors = {}, {}
    for name, src in (("export", root / "export"), ("ipin", ipin.save(root / "ipin.h5"))):
        summary = track(src, "phone", root / f"track_{name}", radiomap=folder)
        assert summary["radiomap"]["used"] and summary["radiomap"]["positions"] > 50
        assert summary["anchoring"]["method"] == "smooth"
        assert summary["radiomap"]["floor_by"].startswith("barometer")  # the export's Barometer.csv
        floors[name] = pd.read_csv(root / f"track_{name}" / "trajectory.csv")["floor"].to_numpy()
        geojson = json.loads((root / f"track_{name}" / "trajectory.geojson").read_text())
        line = next(f for f in geojson["features"] if f["geometry"]["type"] == "LineString")
        paths[name] = np.asarray(line["geometry"]["coordinates"])  # lon, lat
    np.testing.assert_array_equal(floors["export"], floors["ipin"])
    assert set(np.unique(floors["ipin"])) == {-2.0, -1.0, 0.0}  # the walk goes down two floors and back
    a, b = paths["export"], paths["ipin"]
    assert a.shape == b.shape
    gap = np.linalg.norm(
        geo.latlon_to_local(a[:, 1], a[:, 0], b[0, 1], b[0, 0])
        - geo.latlon_to_local(b[:, 1], b[:, 0], b[0, 1], b[0, 0]),
        axis=1,
    )
    print(f"\nthe export's path vs the IPIN import's: median {np.median(gap):.3f} m, max {gap.max():.3f} m")
    # measured 0.43 / 1.28 m with the export's origin 38.8 m from the map's: the odometry and the fixes are
    # the same to the millimetre; the smoother has a start-heading prior for the IPIN log only (its AHRS
    # frame is documented east-north-up, Sensor Logger's is not: fuse.calibrate.known_heading_deg); the
    # smoother itself is the same in any frame (every fix moved by (300, -200) m: the same path within 1 mm)
    assert np.median(gap) < 1.0 and gap.max() < 3.0


@pytest.mark.real_data
def test_frames_that_cannot_be_related_are_said_and_a_bare_walk_takes_the_maps(venue):
    rmap, ipin, user, _ = venue
    # a map of a site plan's frame (no lat/lon origin) and a walk with GNSS fixes: not used, said why
    plan_frame = radiomap.RadioMap(rmap.scans, rmap.bssids, rmap.cfg, rmap.sigma_scale, {**rmap.card, "origin": None})
    out, radio, info, warns = radiofixes.with_radio_fixes(user, plan_frame)
    assert not info["used"] and info["why"] == radiofixes.NO_PLACE and not radio.any()
    assert out.fixes is user.fixes and len(warns) == 1 and radiofixes.NO_PLACE in warns[0]
    legacy = radiomap.RadioMap(
        rmap.scans, rmap.bssids, rmap.cfg, rmap.sigma_scale, {k: v for k, v in rmap.card.items() if k != "origin"}
    )
    assert "build it again" in radiofixes.with_radio_fixes(user, legacy)[2]["why"]
    # a walk with neither fixes nor an origin (indoors, no GNSS) lies where the map does
    meta = {k: v for k, v in ipin.meta.items() if k not in ("origin_lat", "origin_lon")}
    bare = dataclasses.replace(ipin, fixes=None, meta=meta)
    out, radio, info, warns = radiofixes.with_radio_fixes(bare, rmap)
    assert info["used"] and radio.all() and not warns
    assert (out.meta["origin_lat"], out.meta["origin_lon"]) == rmap.origin
    np.testing.assert_allclose(out.fixes.pos[:, :2], rmap.locate(ipin.wifi, by_group=False).xy)
