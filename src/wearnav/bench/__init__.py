"""The papers' experiments and measurements: run lists, table builders, the efficiency benchmark."""
