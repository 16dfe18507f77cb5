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


def test_schedule_warm_up_then_cosine_to_its_floor():
    from wearnav.train.common import Schedule

    s = Schedule(warmup_steps=10, total_steps=110, final=0.01)
    assert s(0) == pytest.approx(0.1) and s(4) == pytest.approx(0.5) and s(9) == pytest.approx(1.0)
    assert s(10) == pytest.approx(1.0)
    assert s(60) == pytest.approx(0.01 + 0.99 * 0.5)  # half-way through the cosine
    assert s(110) == pytest.approx(0.01) and s(500) == pytest.approx(0.01)
    assert all(s(i) >= s(i + 1) for i in range(10, 120))
    assert Schedule()(0) == Schedule()(10_000) == 1.0  # no schedule: constant
    ramp = Schedule(total_steps=100, aux_warmup_steps=40)
    assert ramp.aux(0) == 0.0 and ramp.aux(10) == pytest.approx(0.25) and ramp.aux(40) == ramp.aux(99) == 1.0
    assert Schedule().aux(0) == 1.0  # no ramp: the auxiliary losses count from the start
    held = Schedule(warmup_steps=10, total_steps=110, decay_from=60)
    assert (
        held(30) == held(60) == 1.0
        and held(85) == pytest.approx(0.01 + 0.99 * 0.5)
        and held(110) == pytest.approx(0.01)
    )
