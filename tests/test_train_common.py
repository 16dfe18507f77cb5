"""train.common: checkpoints are saved atomically and durably (AtomicCheckpointIO)."""

import os

import pytest
import torch

from wearnav.train import common
from wearnav.train.common import AtomicCheckpointIO, make_trainer


def test_every_trainer_saves_checkpoints_through_atomic_io(tmp_path):
    trainer, _, _ = make_trainer(tmp_path, epochs=1, max_minutes=None, progress=False, steps_per_epoch=1)
    assert isinstance(trainer.strategy.checkpoint_io, AtomicCheckpointIO)


def test_a_save_killed_midway_keeps_the_previous_checkpoint(tmp_path, monkeypatch):
    path = tmp_path / "checkpoints" / "last.ckpt"
    io = AtomicCheckpointIO()
    io.save_checkpoint({"epoch": 1, "w": torch.ones(3)}, path)
    fsynced = []
    real_fsync = os.fsync
    monkeypatch.setattr(os, "fsync", lambda fd: (fsynced.append(fd), real_fsync(fd))[1])
    io.save_checkpoint({"epoch": 2, "w": torch.ones(3)}, path)
    assert len(fsynced) == 2  # the file, then its folder
    assert torch.load(path, weights_only=False)["epoch"] == 2

    def torn_save(obj, f):
        with open(f, "wb") as fh:
            fh.write(b"PK\x03\x04 half a checkpoint")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(common.torch, "save", torn_save)
    with pytest.raises(OSError):
        io.save_checkpoint({"epoch": 3, "w": torch.zeros(3)}, path)
    monkeypatch.undo()
    assert torch.load(path, weights_only=False)["epoch"] == 2
    assert sorted(p.name for p in path.parent.iterdir()) == ["last.ckpt"]
