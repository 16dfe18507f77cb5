"""A stored live session → a wearnav dataset folder (what ``wearnav import`` writes), which
``track``, ``classify`` and the benchmarks read."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from wearnav.dataset import Dataset, DatasetWriter
from wearnav.errors import MissingFileError
from wearnav.live.buffer import SessionBuffer
from wearnav.live.store import open_store, store_missing
from wearnav.live.store_pg import is_url, redact


def export_session(store_path: str | Path, session_id: str, out: str | Path):
    """Write the whole session (the importer's checks included; its Wi-Fi scans too) as a one-recording dataset;
    ``store_path``: a SQLite file or a ``postgresql://`` URL."""
    if store_missing(store_path):
        raise MissingFileError("no session store here", Path(store_path))
    store = open_store(store_path)
    where = redact(str(store_path)) if is_url(str(store_path)) else Path(store_path).resolve()
    try:
        buf = SessionBuffer.from_store(store, session_id)
    finally:
        store.close()
    rec = buf.recording()
    assert buf.t0_unix_ns is not None  # recording() has found the session's start
    wifi = buf.wifi.scans(buf.t0_unix_ns)  # the Wi-Fi scans pushed (wearnav.live.wifi), for track --radiomap
    if wifi is not None:
        rec = dataclasses.replace(rec, wifi=wifi)
    with DatasetWriter(out, {"importer": "wearnav live", "store": str(where), "session": session_id}) as writer:
        writer.add(rec)
    return Dataset.open(out)


__all__ = ["export_session"]
