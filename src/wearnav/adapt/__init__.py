"""Adapting a trained odometry model to a user's own walks from the phone's location fixes
(issue 18 §3): :mod:`.segments` (fix-labelled segments, the odometry over them),
:mod:`.finetune` (the ``finetune`` method), :mod:`.run` (`wearnav adapt`: methods, the run folder)."""

from wearnav.adapt.run import DEFAULT_METHOD, METHODS, AdaptConfig, adapt, read_recordings

__all__ = ["AdaptConfig", "DEFAULT_METHOD", "METHODS", "adapt", "read_recordings"]
