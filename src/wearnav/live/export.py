"""A stored live session → a wearnav dataset folder (what ``wearnav import`` writes), which
``track``, ``classify`` and the benchmarks read."""

from __future__ import annotations

from pathlib import Path

from wearnav.dataset import Dataset, DatasetWriter
from wearnav.errors import MissingFileError
from wearnav.live.buffer import SessionBuffer
from wearnav.live.store import open_store, store_missing
from wearnav.live.store_pg import is_url, redact


def export_session(store_path: str | Path, session_id: str, out: str | Path):
    """Write the whole session (the importer's checks included) as a one-recording dataset;
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
    with DatasetWriter(out, {"importer": "wearnav live", "store": str(where), "session": session_id}) as writer:
        writer.add(rec)
    return Dataset.open(out)


__all__ = ["export_session"]
