"""A stored live session → a wearnav dataset folder (what ``wearnav import`` writes), which
``track``, ``classify`` and the benchmarks read."""

from __future__ import annotations

from pathlib import Path

from wearnav.dataset import Dataset, DatasetWriter
from wearnav.errors import MissingFileError
from wearnav.live.buffer import SessionBuffer
from wearnav.live.store import Store


def export_session(store_path: str | Path, session_id: str, out: str | Path):
    """Write the whole session (the importer's checks included) as a one-recording dataset."""
    store_path = Path(store_path)
    if not store_path.is_file():
        raise MissingFileError("no session store here", store_path)
    store = Store(store_path)
    try:
        buf = SessionBuffer.from_store(store, session_id)
    finally:
        store.close()
    rec = buf.recording()
    with DatasetWriter(
        out, {"importer": "wearnav live", "store": str(store_path.resolve()), "session": session_id}
    ) as writer:
        writer.add(rec)
    return Dataset.open(out)


__all__ = ["export_session"]
