"""Every session's tracker, updated together: :class:`Crowd` (issue 37, "one update for everyone").

One thread runs ticks. A tick takes every session poked since the last one (a push acknowledged)
and every session quiet for ``SESSION_END_S`` (its last windows made final, once), runs the first
half of each tracker's update (:meth:`wearnav.live.tracker.LiveTracker.begin`: the new input and
its windows; their input aligned once for all of them, issue 61 §2: ``align_steps``), then the
model **once** for all the windows of all those sessions (one forward pass
per model: phone-only sessions share their default model, three-device ones the shipped one; on the device
:class:`wearnav.live.models.SharedModels` chose), and hands each session its velocities
(:meth:`~wearnav.live.tracker.LiveTracker.finish`: path, fusion, activity, page). Ticks start at
most every ``TICK_S``, so that a busy server batches more sessions per forward pass, and a slow
tick makes the next one take more: the path of every session trails its pushes by about one tick
plus the tracker's own step (``wearnav.live.tracker.STEP_S``), not by a queue that grows.

A tracker is made in this thread (loading a model must not hold up a 200); one that cannot be
made, or fails, is a warning on that session's page, never a failed push, and never stops the
other sessions. A tracker without ``begin`` / ``finish`` (a stand-in in tests) is updated whole.

Decision: docs/decisions/0028-live-crowd.md.
"""

from __future__ import annotations

import dataclasses
import logging
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import torch

from wearnav.live.models import classify_windows, predict_windows

log = logging.getLogger("wearnav.live")
SESSION_END_S = 30.0  # a session without a push this long has ended: its last windows made final
TICK_S = 0.1  # ticks start at most this often (s): pokes in between are batched into one tick
MAX_BATCH = 4096  # windows per forward pass (bounds the memory of one pass)


@dataclasses.dataclass
class _Session:
    buf: Any  # a SessionBuffer
    tracker: Any = None
    error: str | None = None
    pending_since: float | None = None  # the oldest acknowledged push not yet on the page (perf_counter)
    last_push: float = dataclasses.field(default_factory=time.perf_counter)
    ended: bool = False  # made final since its last push
    broken: bool = False  # its tracker could not be made
    latency_s: list = dataclasses.field(
        default_factory=list
    )  # oldest ack not on the page → the update that put it there


class Crowd:
    """The trackers of many sessions, made by ``tracker_factory()`` and updated in ticks (module
    docstring); :meth:`poke` from any thread, :meth:`state` from any thread."""

    def __init__(self, tracker_factory: Callable[[], Any], tick_s: float = TICK_S):
        self._factory = tracker_factory
        self.tick_s = float(tick_s)
        self.sessions: dict[str, _Session] = {}
        self.ticks = 0
        self.tick_s_taken: list[float] = []  # wall time of each tick that updated something
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._run, name="live-crowd", daemon=True)
        self.thread.start()

    def poke(self, sid: str, buf, since: float | None = None) -> None:
        """Session ``sid`` (its buffer ``buf``) has new data, acknowledged at ``since``
        (``time.perf_counter()``; None: now)."""
        now = time.perf_counter()
        since = now if since is None else min(since, now)
        with self._lock:
            s = self.sessions.get(sid)
            if s is None:
                s = self.sessions[sid] = _Session(buf)
            s.pending_since = since if s.pending_since is None else min(s.pending_since, since)
            s.last_push, s.ended = now, False
        self._wake.set()

    def stop(self) -> None:
        self._stop.set()
        self._wake.set()
        self.thread.join(10)

    def state(self, sid: str) -> dict | None:
        """The session's page state with its tracker's error as a warning; None: no tracker yet."""
        s = self.sessions.get(sid)
        if s is None or (s.tracker is None and s.error is None):
            return None
        st = dict(s.tracker.state()) if s.tracker is not None else {}
        if s.error:
            st["warnings"] = [*st.get("warnings", []), s.error]
        return st

    def state_key(self, sid: str) -> tuple | None:
        """What :meth:`state` is made from: (the tracker's state object, which an update replaces
        when it changes: compare with ``is``; the error); None: no state yet."""
        s = self.sessions.get(sid)
        if s is None or (s.tracker is None and s.error is None):
            return None
        return (s.tracker.state() if s.tracker is not None else None, s.error)

    def latency_s(self) -> dict[str, list[float]]:
        return {sid: s.latency_s[-1000:] for sid, s in list(self.sessions.items())}

    # ---- the ticks ---------------------------------------------------------------------------

    def _run(self) -> None:
        while not self._stop.is_set():
            self._wake.wait(timeout=1.0)  # also wakes for sessions that went quiet
            if self._stop.is_set():
                return
            self._wake.clear()
            tic = time.perf_counter()
            try:
                if self.tick():
                    self.tick_s_taken.append(time.perf_counter() - tic)
                    del self.tick_s_taken[:-10_000]
            except Exception:  # a bug here must not stop every session's tracking
                log.exception("live tracking tick failed")
            rest = self.tick_s - (time.perf_counter() - tic)
            if rest > 0:
                self._stop.wait(rest)

    def tick(self) -> int:
        """One tick (module docstring): how many sessions were updated."""
        now = time.perf_counter()
        due: list[tuple[_Session, bool, float | None]] = []
        with self._lock:
            for s in self.sessions.values():
                if s.pending_since is not None:
                    due.append((s, False, s.pending_since))
                    s.pending_since = None
                elif not s.ended and now - s.last_push >= SESSION_END_S:
                    s.ended = True
                    due.append((s, True, None))
        if not due:
            return 0
        self.ticks += 1
        whole, steps = [], []  # (session, final, since) updated whole; (session, step, since) in halves
        for s, final, since in due:
            if not self._ensure_tracker(s):
                continue
            if not hasattr(s.tracker, "begin"):
                whole.append((s, final, since))
                continue
            try:
                batched = hasattr(type(s.tracker), "align_steps")
                step = s.tracker.begin(s.buf, final, batch=True) if batched else s.tracker.begin(s.buf, final)
            except Exception as exc:
                self._failed(s, exc)
                continue
            if step is None:  # nothing to do yet (the tracker waits for more): still pending
                self._still_pending(s, since)
            else:
                steps.append((s, step, since))
        steps = self._align(steps)
        vels = self._forward([(s.tracker.model, step) for s, step, _ in steps])
        acts = self._activities([(s, step) for s, step, _ in steps])
        for (s, step, since), vel, act in zip(steps, vels, acts):
            try:
                changed = bool(s.tracker.finish(step, vel, act))
                s.error = None
            except Exception as exc:
                self._failed(s, exc)
                changed = False
            self._done(s, since, changed)
        for s, final, since in whole:
            try:
                changed = bool(s.tracker.update(s.buf, final=final))
                s.error = None
            except Exception as exc:
                self._failed(s, exc)
                changed = False
            self._done(s, since, changed)
        return len(due)

    def _align(self, steps: list[tuple[_Session, Any, float | None]]) -> list[tuple[_Session, Any, float | None]]:
        """Every step's input aligned and windowed at once, per tracker class
        (``align_steps``: one rotation and one stacked low-pass for all due sessions, issue 61 §2);
        where that fails, each session alone, so that one session's bad input fails only its own."""
        groups: dict[type, list[tuple[Any, Any]]] = {}
        for s, step, _ in steps:
            if getattr(step, "job", None) is not None:
                groups.setdefault(type(s.tracker), []).append((s.tracker, step))
        failed: set[int] = set()
        for cls, work in groups.items():
            try:
                cls.align_steps(work)  # type: ignore[attr-defined]
            except Exception:
                for s, step, _ in steps:
                    if getattr(step, "job", None) is None or type(s.tracker) is not cls:
                        continue
                    try:
                        cls.align_steps([(s.tracker, step)])
                    except Exception as exc:
                        self._failed(s, exc)
                        failed.add(id(step))
        return [x for x in steps if id(x[1]) not in failed]

    @staticmethod
    def _forward(work: list[tuple[Any, Any]]) -> list[np.ndarray | None]:
        """Each step's velocities: one forward pass per model over every step's windows (in chunks
        of ``MAX_BATCH``), split back in order."""
        out: list[np.ndarray | None] = [None] * len(work)
        groups: dict[int, list[int]] = {}
        for i, (model, step) in enumerate(work):
            if step.x is not None:
                groups.setdefault(id(model), []).append(i)
        for idx in groups.values():
            model = work[idx[0]][0]
            x = torch.cat([work[i][1].x for i in idx])
            mask = torch.cat([work[i][1].mask for i in idx])
            vel = np.concatenate(
                [
                    predict_windows(model, x[k : k + MAX_BATCH], mask[k : k + MAX_BATCH])
                    for k in range(0, len(x), MAX_BATCH)
                ]
            )
            ends = np.cumsum([len(work[i][1].x) for i in idx])
            for i, part in zip(idx, np.split(vel, ends[:-1])):
                out[i] = part
        return out

    @staticmethod
    def _activities(work: list[tuple[_Session, Any]]) -> list[tuple[Any, np.ndarray] | None]:
        """Each step's activity windows and their probabilities (None: no label due): one forward
        pass per classifier over every step's windows (:func:`wearnav.live.models.classify_windows`)."""
        out: list[tuple[Any, np.ndarray] | None] = [None] * len(work)
        groups: dict[int, list[tuple[int, Any]]] = {}
        found: dict[int, Any] = {}
        by_class: dict[type, list[int]] = {}  # trackers that window many sessions at once (issue 61 §2)
        for i, (s, _step) in enumerate(work):
            if getattr(s.tracker, "batched", False) and hasattr(type(s.tracker), "activity_windows_many"):
                by_class.setdefault(type(s.tracker), []).append(i)
        for cls, idx in by_class.items():
            try:
                found.update(zip(idx, cls.activity_windows_many([(work[i][0].tracker, work[i][1]) for i in idx])))  # type: ignore[attr-defined]
            except Exception:  # each on its own below: one session's failure is its own
                pass
        for i, (s, step) in enumerate(work):
            try:
                w = found[i] if i in found else s.tracker.activity_windows(step)
            except Exception as exc:  # this session's label is skipped, its path still finishes
                log.warning("session %s: activity failed: %s: %s", s.buf.session_id, type(exc).__name__, exc)
                continue
            if w is not None:
                groups.setdefault(id(s.tracker.classifier[0]), []).append((i, w))
        for members in groups.values():
            model = work[members[0][0]][0].tracker.classifier[0]
            for (i, w), prob in zip(members, classify_windows(model, [w for _, w in members])):
                out[i] = (w, prob)
        return out

    def _ensure_tracker(self, s: _Session) -> bool:
        if s.tracker is not None:
            return True
        if s.broken:
            return False
        try:
            s.tracker = self._factory()
            return True
        except Exception as exc:
            s.broken = True
            s.error = f"live tracking could not start: {type(exc).__name__}: {exc}"
            log.warning("session %s: %s", s.buf.session_id, s.error)
            return False

    @staticmethod
    def _failed(s: _Session, exc: Exception) -> None:
        """A failure is shown on the session's page; its next push tries again."""
        s.error = f"live tracking failed: {type(exc).__name__}: {exc}"
        log.warning("session %s: %s", s.buf.session_id, s.error)

    def _done(self, s: _Session, since: float | None, changed: bool) -> None:
        if since is None:
            return
        if changed:  # the page's path now holds every push acknowledged since ``since``
            s.latency_s.append(time.perf_counter() - since)
            del s.latency_s[:-10_000]
        else:
            self._still_pending(s, since)

    def _still_pending(self, s: _Session, since: float | None) -> None:
        if since is None:
            return
        with self._lock:
            s.pending_since = since if s.pending_since is None else min(since, s.pending_since)


__all__ = ["Crowd", "SESSION_END_S", "TICK_S"]
