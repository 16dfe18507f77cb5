"""The names of what `wearnav track` writes, apart from :mod:`wearnav.track` so that the command
line checks ``--out`` against them before it imports torch (issue 38)."""

from __future__ import annotations

TRACK_JSON = "track.json"  # the marker: a folder holding it was written by `wearnav track`
TRACK_FILES = ("trajectory.csv", "trajectory.png", "trajectory.html", "trajectory.geojson", "fixes.csv", TRACK_JSON)
