"""``wearnav live --mqtt``: a real Mosquitto broker on 127.0.0.1, Sensor Logger's messages published
to it with paho-mqtt, received, checked and stored as pushes are. Skips with the reason where
Mosquitto (Debian ``mosquitto``) or its websockets listener is absent."""

from __future__ import annotations

import shutil
import sqlite3
import subprocess
import time
from pathlib import Path

import httpx
import pytest

from wearnav.live.badinputs import body, enc
from wearnav.live.process import LiveServer, free_port

MOSQUITTO = shutil.which("mosquitto") or ("/usr/sbin/mosquitto" if Path("/usr/sbin/mosquitto").is_file() else None)


@pytest.fixture
def broker(tmp_path, request):
    """(scheme, port) of a Mosquitto listening on 127.0.0.1 with the given protocol."""
    if MOSQUITTO is None:
        pytest.skip("mosquitto is not installed (Debian: apt-get install mosquitto)")
    scheme = request.param
    port = free_port()
    conf = tmp_path / "mosquitto.conf"
    conf.write_text(
        f"listener {port} 127.0.0.1\n" + ("protocol websockets\n" if scheme == "ws" else "") + "allow_anonymous true\n"
    )
    log = tmp_path / "mosquitto.log"
    with open(log, "wb") as f:
        proc = subprocess.Popen([MOSQUITTO, "-c", str(conf), "-v"], stdout=f, stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 10
        while "running" not in log.read_text(errors="replace"):
            if proc.poll() is not None:
                pytest.skip(
                    f"this mosquitto cannot open a {scheme} listener on 127.0.0.1 (built without "
                    f"websockets?): {log.read_text(errors='replace').strip().splitlines()[-1]}"
                )
            if time.monotonic() > deadline:
                pytest.fail("mosquitto did not start")
            time.sleep(0.05)
        yield scheme, port
    finally:
        if proc.poll() is None:
            proc.terminate()
            proc.wait(10)


@pytest.mark.parametrize("broker", ["ws", "mqtt"], indirect=True)
def test_mqtt_messages_are_received_and_stored(tmp_path, broker):
    import paho.mqtt.client as mqtt

    scheme, port = broker
    db = tmp_path / "live.db"
    with LiveServer(db, "--no-track", "--mqtt", f"{scheme}://127.0.0.1:{port}/sensor-logger") as srv:
        deadline = time.monotonic() + 15
        while "mqtt: subscribed" not in srv.output():
            assert time.monotonic() < deadline, srv.output()
            time.sleep(0.05)
        pub = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, transport="websockets" if scheme == "ws" else "tcp")
        if scheme == "ws":
            pub.ws_set_options(path="/mqtt")
        pub.connect("127.0.0.1", port)
        pub.loop_start()
        try:
            for k in range(5):
                pub.publish("sensor-logger", enc(body(sessionId="mq", messageId=k)), qos=0).wait_for_publish(5)
            pub.publish("sensor-logger", enc(body(sessionId="mq", messageId=2)), qos=0).wait_for_publish(5)  # repeat
            pub.publish(
                "sensor-logger", enc(body(sessionId="mq", messageId=9)).replace(b"0.1", b"NaN"), qos=0
            ).wait_for_publish(5)  # refused
        finally:
            pub.loop_stop()
            pub.disconnect()
        deadline = time.monotonic() + 10
        while True:
            r = httpx.get(f"{srv.url}/stats").json()
            if r["accepted"] + r["repeats"] >= 6 or time.monotonic() > deadline:
                break
            time.sleep(0.05)
        assert (r["accepted"], r["repeats"]) == (5, 1)
        assert "message refused (400)" in srv.output()
    with sqlite3.connect(db) as c:
        assert sorted(m for (m,) in c.execute("SELECT message_id FROM messages WHERE session_id='mq'")) == list(
            range(5)
        )
