"""What receiving and tracking cost (issue 61): ``wearnav live cost receiver`` posts pushes over real
HTTP to a real receiver and reads its CPU; the bench page turns its figures into a process's and
the machine's capacity."""

from __future__ import annotations

import pytest

from wearnav.live.bench_page import costs
from wearnav.live.cost import receiver_cost


@pytest.mark.slow  # ~20 s on 2 cores: a simulated walk, then a server starts
def test_receiver_cost_posts_every_message_and_reads_the_receivers_cpu(tmp_path):
    r = receiver_cost(messages=60, walkers=6, senders=3, rate=200.0, work=tmp_path)
    assert r["messages"] == 60 and r["stored"] == 60  # every push acknowledged and in the store
    assert 0 < r["receiver_ms_per_message"] < 100 and r["receiver_cpu_s"] > 0
    assert 40 < r["samples_per_message"] < 120 and r["bytes_per_message"] > 5000  # 0.2 s of a phone's sensors
    assert r["store"] == "sqlite"


def test_the_page_turns_costs_into_capacity():
    """Receiver: CPU share × wall / messages; tracking: a row's CPU less its messages at that cost,
    per walker-second; capacity: a core's worth of each, and the machine's cores over both."""
    r = {
        "load": {"cpu_share_of_one_core": 0.1, "wall_s": 60.0, "messages": 3000},  # 2 ms a message
        "machine": {"cores": 2},
        "walkers": [
            {"tracking": True, "kept_up": True, "walkers": 10, "seconds": 30.0, "messages": 1500,
             "cpu_share_of_one_core": 0.4, "devices": "phone"},  # 12 s CPU, 3 s of it receiving: 30 ms/walker-s
            {"tracking": True, "kept_up": False, "walkers": 20, "seconds": 30.0, "messages": 3000,
             "cpu_share_of_one_core": 0.9, "devices": "phone"},  # not kept up: not a cost
        ],
    }  # fmt: skip
    c = costs(r)
    assert c["receiver_ms_per_message"] == 2.0 and c["tracker_ms_per_walker_s"] == {"phone-10": 30.0}
    assert c["messages_per_s_per_receiver_core"] == 500 and c["walkers_per_receiver_core"] == 100
    assert c["walkers_per_tracker_core"] == 33
    assert c["walkers_per_machine"] == int(2 / (0.002 * 5 + 0.030))  # 50
