"""The harmonised activity label set (issue 35 §1): every source's mapping is checked against the
label names its importer actually writes (real slices of ../shared/data, and the simulator's
activity track), so a source label missing from the table fails here."""

from __future__ import annotations

import numpy as np
import pytest

from wearnav import activity_labels as al
from wearnav.importers import ilc2, ipin2023, motionsense, oxford_steps, uci_hapt, uji_phone_watch
from wearnav.simulate.scenario import Episode, Scenario


def _values(recs, kind: str) -> set[str]:
    return {v for r in recs for v in r.labels.loc[r.labels["kind"] == kind, "value"]}


def test_every_mapping_lands_in_the_label_set():
    for source, (_, table) in al.MAPPINGS.items():
        for raw, label in table.items():
            assert label is None or label in al.LABELS, (source, raw, label)
            assert al.unify(source, raw) == label
    assert set(al.WHOLE_RECORDING.values()) <= set(al.LABELS)
    assert al.UNKNOWN not in al.LABELS
    # the card's table: one row per source label and per whole-recording source
    n = sum(len(m) for _, m in al.MAPPINGS.values()) + len(al.WHOLE_RECORDING)
    assert len(al.mapping_table()) == n
    with pytest.raises(KeyError):
        al.unify("motionsense", "cycling")


def test_motionsense_labels_are_the_importers():
    kind, table = al.MAPPINGS["motionsense"]
    assert kind == "activity" and set(table) == set(motionsense.ACTIVITIES.values())


@pytest.mark.real_data
def test_uci_hapt_labels_are_its_activity_file(shared_data):
    names = uci_hapt.read_activity_names(shared_data / "uci_hapt" / "activity_labels.txt")
    kind, table = al.MAPPINGS["uci-hapt"]
    assert set(table) == set(names.values())
    (rec,) = uci_hapt.read(shared_data / "uci_hapt", limit=1)
    assert _values([rec], kind) <= set(table)


@pytest.mark.real_data
def test_uji_labels_are_the_imported_ones(shared_data):
    recs = list(uji_phone_watch.read(shared_data / "uji_phone_watch_har", limit=2))
    for source in ("uji-phone", "uji-watch"):
        kind, table = al.MAPPINGS[source]
        seen = _values(recs, kind)
        assert seen and seen <= set(table), (source, seen)
    # the dataset's documented five labels, all mapped
    assert set(al.MAPPINGS["uji-phone"][1]) == {"SEATED", "STANDING_UP", "WALKING", "TURNING", "SITTING_DOWN"}


def test_simulator_activity_track_is_mapped():
    sc = Scenario(
        duration=60.0,
        bouts=[(2.0, 10.0), (20.0, 30.0), (40.0, 50.0)],
        episodes=[
            Episode("sit", 10.0, 20.0, (11.0, 12.0), (17.0, 18.0)),
            Episode("squat", 30.0, 40.0, (31.0, 32.0), (37.0, 38.0)),
            Episode("stand", 50.0, 55.0),
        ],
    )
    rows = [r for r in sc.label_rows("DLW") if r[2] == "activity"]
    kind, table = al.MAPPINGS["sim"]
    assert kind == "activity"
    assert {r[3] for r in rows} == set(table)  # every label the track can write, and no other


@pytest.mark.real_data
def test_whole_recording_sources_have_no_activity_labels(shared_data):
    """ILC2, IPIN and Oxford carry no activity track of their own: their walks are labelled whole."""
    recs = [
        next(iter(ilc2.read(shared_data / "ilc2_indoor_location", limit=1))),
        next(iter(ipin2023.read(shared_data / "ipin2023_track3", limit=1))),
        next(iter(oxford_steps.read(shared_data / "oxford_step_counter", limit=1))),
    ]
    for rec in recs:
        assert "activity" not in set(rec.labels["kind"]), rec.name
    assert recs[0].meta["mode"] == "walk" and recs[1].meta["mode"] == "walk"
    assert recs[2].devices["phone"].gyro is None  # accelerometer only, as the module says
    assert np.isfinite(recs[1].truth.floor).all()  # IPIN's floors: what the floor-change rule reads
