"""What receiving and tracking cost (issue 61): ``wearnav live cost receiver`` posts pushes over real
HTTP to a real receiver and reads its CPU; the bench page turns its figures into a process's and
the machine's capacity."""

from __future__ import annotations

import pytest

from wearnav.live.bench_page import _cost_rows, costs
from wearnav.live.cost import receiver_cost


@pytest.mark.slow  # ~20 s on 2 cores: a simulated walk, then a server starts
def test_receiver_cost_posts_every_message_and_reads_the_receivers_cpu(tmp_path):
    r = receiver_cost(messages=60, walkers=6, senders=3, rate=200.0, work=tmp_path)
    assert r["messages"] == 60 and r["stored"] == 60  # every push acknowledged and in the store
    assert 0 < r["receiver_ms_per_message"] < 100 and r["receiver_cpu_s"] > 0
    assert 40 < r["samples_per_message"] < 120 and r["bytes_per_message"] > 5000  # 0.2 s of a phone's sensors
    assert r["store"] == "sqlite"


@pytest.mark.slow  # ~25 s on 2 cores: a simulated walk, then the receiver and the floor's server start
def test_receiver_cost_measures_the_http_servers_floor_under_the_same_pushes(tmp_path):
    """``--floor``: the same pushes, each answered 200 by a real uvicorn process serving an app that
    only reads the body (a sender that got anything else fails the call); its CPU a message beside
    the receiver's, and the difference."""
    r = receiver_cost(messages=200, walkers=10, senders=4, rate=400.0, work=tmp_path, floor=True)
    assert r["stored"] == 200
    floor = r["server_floor_ms_per_message"]
    assert 0 < floor < 100  # 200 bodies of ~14 kB read over HTTP: some CPU, counted from /proc
    assert r["receiver_above_floor_ms_per_message"] == pytest.approx(r["receiver_ms_per_message"] - floor, abs=1e-3)


def test_the_page_turns_costs_into_capacity():
    """Costs from the rows that kept up only, measured, not subtracted: a row's CPU per walker-second;
    with tracker processes the receiver's own CPU per message and the trackers' per walker-second;
    capacity from the largest crowd kept up."""
    r = {
        "load": {"cpu_share_of_one_core": 0.1, "wall_s": 60.0, "messages": 3000},  # 2 ms a message
        "machine": {"cores": 2},
        "walkers": [
            {"tracking": True, "kept_up": True, "walkers": 10, "seconds": 30.0, "messages": 1500,
             "cpu_share_of_one_core": 0.4, "devices": "phone"},  # in the receiver: 40 ms/walker-s in all
            {"tracking": True, "kept_up": True, "walkers": 20, "seconds": 30.0, "messages": 3000,
             "cpu_share_of_one_core": 0.6, "receiver_cpu_share_of_one_core": 0.1,
             "devices": "phone"},  # tracker processes: 1 ms a message, 25 ms/walker-s tracking
            {"tracking": True, "kept_up": False, "walkers": 40, "seconds": 30.0, "messages": 6000,
             "cpu_share_of_one_core": 0.9, "devices": "phone"},  # not kept up: not a cost
        ],
    }  # fmt: skip
    c = costs(r)
    assert c["load_receiver_ms_per_message"] == 2.0
    assert c["server_ms_per_walker_s"] == {"phone-10": 40.0, "phone-20": 30.0}
    assert c["receiver_ms_per_message"] == {"phone-20": 1.0} and c["tracker_ms_per_walker_s"] == {"phone-20": 25.0}
    assert c["largest_kept_up"] == "phone-20" and c["walkers_per_core"] == 33
    assert c["walkers_per_tracker_core"] == 40 and c["messages_per_s_per_receiver_core"] == 1000
    assert c["walkers_per_machine_estimate"] == 66
    text = "\n".join(_cost_rows(c, 2))
    assert "1 (the receiver process at 20 walkers)" in text and "25 (the tracker processes at 20 walkers)" in text
    assert "measured: 20 walkers kept up" in text
