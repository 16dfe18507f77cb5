"""Sensor Logger's second transport: MQTT publishing (PUSHING.md: the same JSON as HTTP Push, QoS 0,
websockets only on the app's side).

``wearnav live --mqtt ws://user:password@broker:8000/sensor-logger`` subscribes to the topic (the
URL's path; default ``sensor-logger``, the app's) with paho-mqtt over websockets (``ws://``,
``wss://``; ``mqtt://`` / ``mqtts://`` over TCP) and hands every message to the receiver as if it
had been pushed: the same checks (:mod:`wearnav.live.push`), the same store, one row per
(session, device, messageId). The URL's query may say ``platform`` and ``standardisation`` as the
push URL does. A refused message is logged (one line) and dropped: MQTT has no answer to send.
"""

from __future__ import annotations

import logging
from urllib.parse import parse_qsl, unquote, urlsplit

from wearnav.errors import ConfigError
from wearnav.live.app import settings
from wearnav.live.push import BadPush

log = logging.getLogger("wearnav.live")
SCHEMES = {
    "ws": ("websockets", False, 80),
    "wss": ("websockets", True, 443),
    "mqtt": ("tcp", False, 1883),
    "mqtts": ("tcp", True, 8883),
}
DEFAULT_TOPIC = "sensor-logger"
WS_PATH = "/mqtt"


def parse_url(url: str) -> dict:
    parts = urlsplit(url)
    if parts.scheme not in SCHEMES or not parts.hostname:
        raise ConfigError(f"--mqtt {url!r}: expected ws://broker:port/topic (or wss://, mqtt://, mqtts://)")
    transport, tls, port = SCHEMES[parts.scheme]
    query = dict(parse_qsl(parts.query))
    return {
        "transport": transport,
        "tls": tls,
        "host": parts.hostname,
        "port": parts.port or port,
        "topic": unquote(parts.path.lstrip("/")) or DEFAULT_TOPIC,
        "username": unquote(parts.username) if parts.username else None,
        "password": unquote(parts.password) if parts.password else None,
        "query": query,
    }


def subscribe(url: str, receiver):
    """Start a paho client (its own thread) feeding ``receiver`` (:class:`wearnav.live.app.Receiver`);
    returns it (``client.loop_stop()`` ends it)."""
    import paho.mqtt.client as mqtt
    from paho.mqtt.enums import CallbackAPIVersion  # where paho 2 defines it (the client re-exports it)

    cfg = parse_url(url)
    try:
        platform, standardised = settings(cfg["query"], receiver.platform, receiver.standardised)
    except BadPush as exc:
        raise ConfigError(f"--mqtt: {exc.message}") from None
    client = mqtt.Client(CallbackAPIVersion.VERSION2, transport=cfg["transport"])
    if cfg["transport"] == "websockets":
        client.ws_set_options(path=WS_PATH)
    if cfg["tls"]:
        client.tls_set()
    if cfg["username"]:
        client.username_pw_set(cfg["username"], cfg["password"])

    def on_connect(client, userdata, flags, reason_code, properties):
        client.subscribe(cfg["topic"], qos=0)
        log.info("mqtt: subscribed to %r on %s:%s", cfg["topic"], cfg["host"], cfg["port"])

    def on_message(client, userdata, msg):
        if len(msg.payload) > receiver.max_body:
            log.info("mqtt: message of %d bytes over the limit of %d, dropped", len(msg.payload), receiver.max_body)
            return
        try:
            receiver.accept(msg.payload, platform, standardised)
        except BadPush as exc:
            log.info("mqtt: message refused (%d): %s", exc.status, exc.message)

    client.on_connect, client.on_message = on_connect, on_message
    client.connect_async(cfg["host"], cfg["port"], keepalive=30)
    client.loop_start()
    return client


__all__ = ["parse_url", "subscribe"]
