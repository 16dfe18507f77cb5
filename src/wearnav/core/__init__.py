"""Foundations every layer uses: errors aside, files written atomically (fileio), text read
whatever its compression (textio), progress, provenance, interrupts, rotations, clocks
(timeseries) and lat/lon (geo). They import nothing of wearnav above them."""
