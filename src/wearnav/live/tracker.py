"""The live path and activity of one session as its samples arrive: :class:`LiveTracker`.

Odometry, the way ``track`` runs it (:func:`wearnav.track.odometry`), piece by piece. The session's
model clock is ``t0 + k / rate`` (``t0`` the devices' common start as :func:`wearnav.preprocess.align`
finds it, decided once the devices that start together have started) and its windows start at every
``stride``-th clock sample, as :class:`wearnav.preprocess.windows.WindowDataset` cuts them offline. An update
(once ``STEP_S`` more of the session has arrived) aligns only the clock from ``CONTEXT_S`` before the
first window not yet final up to the data's end (:meth:`SessionBuffer.covered_until`) and predicts the
windows that end ``LAG_S`` before it (the zero-phase low-pass needs that much data after a window).
A window is final once the data reaches ``LAG_S`` past it for one device, ``FRAME_LAG_S`` for several
(the common frame's yaw, :mod:`wearnav.preprocess.frames`, is a 20-s Gaussian-kernel estimate that needs data on
both sides); the path grows by the final windows' velocities, integrated on from its last position
(Suite-IN++ eq. 8, :func:`wearnav.trajectory.integrate_velocity`), and the windows after them are
predicted again at each update as the path's provisional end. So each window is predicted once (one
device) or about ``FRAME_LAG_S / (STEP_S)`` times (several), never the whole session again.

With one device present the preprocessing is local in time (also for a model whose layout lists
more, as PDR's lists all three: the common frame of one device is its own): each window sees the
input it sees offline, is final ``LAG_S`` after it, and the path is ``track``'s to round-off (the
tests: 1e-6 m). With several, a final window's common frame
comes from ``CONTEXT_S`` before it to ``FRAME_LAG_S`` after it instead of the whole walk, so the path
differs slightly from ``track``'s (measured in tests/test_live_tracker.py).

Fusion: the final path feeds :class:`wearnav.fuse.live.IncrementalFuser` (``track``'s smoother as a
fixed-lag smoother; before the first final window the provisional path is smoothed whole by
:func:`wearnav.fuse.smooth`), solved at most every ``FUSE_EVERY_S``; the path since the last solve is
placed by a rigid fit (:func:`wearnav.fuse.rigid_fit`) on the last ``PLACE_S`` of the smoothed one.
Everything is in the east/north frame of the first good fix (:class:`wearnav.live.fixframe.FixFrame`);
a radio map's positions of the Wi-Fi scans join the fixes (:class:`wearnav.live.radio.RadioFixes`).
Activity: the phone's latest window classified by the shipped activity model
as ``classify`` runs it (:func:`wearnav.train.labelling.window_classes`; its input:
:mod:`wearnav.live.activity`). Warnings: those the input
gives (:func:`wearnav.track.trust.input_warnings`) once ``TRUST_AFTER_S`` of the session has arrived, and
the smoother's; the walk-plausibility check of ``track`` needs the whole walk and is left to it.

Issue 61 §2, for a crowd: an update's Recording is made straight from the buffer's arrays where the
session is Sensor Logger's phone-only input (:func:`wearnav.live.lean.lean_recording`, the importer's step's numbers
bit for bit), and the aligning is left to :meth:`LiveTracker.align_steps`, which a
:class:`wearnav.live.crowd.Crowd` runs once for every due session
(:func:`wearnav.preprocess.batch.align_many`: one rotation and one stacked low-pass for all, ``align``'s
output to round-off), as it does the activity windows (:meth:`LiveTracker.activity_windows_many`).
``LiveTracker.batched = False`` keeps the per-session path (tests/test_live_batched.py compares them).

Decision: docs/decisions/0022-live-tracking.md.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Any

import numpy as np

from wearnav import fuse, pretrained
from wearnav.fuse.config import FuseResult
from wearnav.fuse.live import IncrementalFuser
from wearnav.fuse.radiomap import RadioMap
from wearnav.live.activity import Job, label_job, label_windows, label_windows_many
from wearnav.live.fixframe import FixFrame
from wearnav.live.lean import lean_recording
from wearnav.live.models import SharedModels, classify_windows, predict_windows
from wearnav.live.pagestate import PageRows
from wearnav.live.radio import RadioFixes
from wearnav.preprocess import Aligned, PreprocessConfig, align, common_span
from wearnav.preprocess.batch import align_many
from wearnav.preprocess.windows import WindowConfig, WindowDataset, turn
from wearnav.recording import Recording
from wearnav.track import odometry_preprocess, path_times
from wearnav.track.trust import input_warnings
from wearnav.train.labelling import UNKNOWN_INDEX, Windows, class_name, decide_classes, unknown_note
from wearnav.train.odometry import TrainConfig
from wearnav.trajectory import integrate_velocity

# Input aligned before the first window not yet final: the common frame's Gaussian kernel (σ 20 s,
# wearnav.preprocess.frames) reaches 4 σ = 80 s back. Measured on a 300-s simulated walk (3 devices), the fused
# live path vs track's: 30 s → 24.6 m max (the frame's estimate goes astray), 60 s → 0.37 m, 90 s → 0.11 m.
CONTEXT_S = 90.0
# One device: no common frame, so the input before a window matters only through the zero-phase
# low-pass's edge (wearnav.preprocess: 4th-order Butterworth at 0.4 × the model rate, 10 Hz for 25 Hz:
# its transient is gone within a second) and the stream's interpolation. Aligning 90 s for every
# update was most of a phone-only session's cost; 10 s keeps each window's input track's to round-off
# (tests/test_live_tracker.py, 1e-4 m), and so does 3 s (issue 61: with the update's Recording and its
# alignment made from arrays, their cost follows the length aligned; 3 s instead of 10 took 0.7-1.5 ms
# off a walker-second, docs/live-scaling.md).
ONE_DEVICE_CONTEXT_S = 3.0
LAG_S = 1.0  # a window is predicted once the data reaches this far past its end (zero-phase filters)
# Several devices: a window is final once the data reaches this far past it (the common frame's yaw,
# wearnav.preprocess.frames, is a 20-s Gaussian kernel estimate: 3 σ); until then it is predicted again at
# every update, as the provisional end of the path.
FRAME_LAG_S = 60.0
# An update works once this much more of the session has arrived (each aligns the context). `wearnav live
# bench`, 3 devices, 0.2-s pushes, 60 s at real time: 1.0 s → push-to-path p95 1.22 s at 15.8 % of a core
# (3 walkers 1.69 s, 65 %); 0.5 s → 0.65 s at 26.8 % (3 walkers 1.26 s, 93 %): the 1-s goal for one.
STEP_S = 0.5
# The smoother is solved at most this often (s of session); the path since is placed rigidly on the
# last PLACE_S of the smoothed one, so the odometry extends the path between solves and push → path
# does not wait for a solve. Issue 61: every 10 s instead of 3 s, the solves' share of a phone-only
# walker's tracking falls from ~18 % to ~6 % (docs/live-scaling.md); the path drawn since the last
# solve may move by a few metres when the next one lands (2.7 m at most on a 120-s walk, measured
# for issue 37), the final path (the session's end) is a solve as before.
FUSE_EVERY_S = 10.0
PLACE_S = 10.0  # ... on the last this many seconds of the smoothed path (wearnav.fuse.rigid_fit)
# The activity label is refreshed at most this often (s of session time). Issue 61: 2 s instead of 1 s
# halves the classifier's share of a walker's tracking (its three-member ensemble sees three windows
# per label: a quarter of the tracking CPU at 1 s); the label is decided over five 2.56-s windows
# (about 6 s of walk: classify's context_windows), so refreshing it every second added little.
ACTIVITY_EVERY_S = 2.0
TRUST_AFTER_S = 30.0  # the input's warnings once this much of the session has arrived
# The model and the clock are chosen once the data reaches this far past align's edge tolerance
# (a device starting later than that after the first counts as put on mid-walk), for the devices'
# batches to have arrived.
START_MARGIN_S = 1.0


@dataclasses.dataclass
class _Odometry:
    """The windows predicted so far and the integrated path (grows by appending)."""

    t_c: list = dataclasses.field(default_factory=list)  # window centres, s
    vel: list = dataclasses.field(default_factory=list)  # (2,) m/s
    t: list = dataclasses.field(default_factory=list)  # path times (clock samples), s
    xy: list = dataclasses.field(default_factory=list)  # (2,) m, from (0, 0) at the first
    _arrays: dict = dataclasses.field(default_factory=dict, repr=False)

    def array(self, name: str) -> np.ndarray:
        """The list ``name`` as a float64 array ((N, 2) for ``vel`` and ``xy``), made from its new
        items only: the lists only grow, and making the whole of them an array at every update
        grew with the session."""
        items = getattr(self, name)
        got = self._arrays.get(name)
        if got is None or len(got) > len(items):
            got = np.zeros((0, 2) if name in ("vel", "xy") else 0)
        if len(got) < len(items):
            new = np.asarray(items[len(got) :], dtype=np.float64).reshape((-1, *got.shape[1:]))
            got = self._arrays[name] = np.concatenate([got, new])
        return got


@dataclasses.dataclass
class Step:
    """One update between :meth:`LiveTracker.begin` and :meth:`LiveTracker.finish`: the session's
    input, and the windows the model is to see (``x`` (N, D, L, 6) float32 world-frame acc + gyro,
    ``mask`` (N, D); None: no window this time)."""

    tic: float  # perf_counter at begin
    final: bool
    rec: Recording  # the session from the context on
    covered: float  # s since t0 (SessionBuffer.covered_until)
    changed: bool  # the fixes changed
    g_final: int  # the last clock sample a final window may use
    clock_t: np.ndarray | None = None  # the aligned clock's times, s
    t_c: np.ndarray | None = None  # window centres, s
    x: Any = None  # torch.Tensor
    mask: Any = None  # torch.Tensor
    yaw: np.ndarray | None = None  # each window's heading ψ where the model has a heading frame
    # the alignment due (LiveTracker.align_steps): the preprocessing, the clock (s), its first
    # sample's index and the last clock sample a window may use; None: done or none due
    job: tuple | None = None
    cpu_tic: float = 0.0  # process_time at begin


class LiveTracker:
    """One session's live path (see module docstring); :meth:`update` from one thread at a time.

    ``model``: an odometry run, exported file or shipped name; None: the shipped model for the
    devices the session starts with (as ``track``). ``activity_model``: a classifier (None: no
    activity). ``context_s``, ``lag_s``, ``frame_lag_s``, ``step_s``: the module's ``CONTEXT_S``,
    ``LAG_S``, ``FRAME_LAG_S``, ``STEP_S``; ``fuse_lag_s`` / ``fuse_step_s``: the fixed-lag
    smoother's window and step. ``models``: where the models come from (:class:`SharedModels`;
    None: loaded for this tracker alone, on the CPU). ``plan``: a GeoJSON floor plan the page draws;
    ``radiomap``: a :class:`wearnav.fuse.radiomap.RadioMap` whose positions of the session's Wi-Fi
    scans join its fixes."""

    def __init__(
        self,
        model: str | Path | None = None,
        activity_model: str | Path | None = "activity",
        context_s: float = CONTEXT_S,
        lag_s: float = LAG_S,
        frame_lag_s: float = FRAME_LAG_S,
        step_s: float = STEP_S,
        fuse_lag_s: float = 300.0,
        fuse_step_s: float = 30.0,
        models: SharedModels | None = None,
        plan: str | Path | None = None,
        radiomap: RadioMap | None = None,
    ):
        self._model_arg = model
        self._radio = RadioFixes(radiomap) if radiomap is not None else None  # the scans' positions join the fixes
        self._page = PageRows(plan)  # what the page draws, kept between updates (the plan drawn under the path)
        self._models = models if models is not None else SharedModels("cpu")
        self.context_s, self.lag_s, self.step_s = float(context_s), float(lag_s), float(step_s)
        self.frame_lag_s = float(frame_lag_s)
        self._fuse_lag = (float(fuse_lag_s), float(fuse_step_s))
        # the odometry model, its training config and file: set by _start
        self.model: Any = None
        self.cfg: TrainConfig | None = None
        self.model_path: Path | None = None
        self.classifier = None
        if activity_model is not None:
            path = pretrained.model_path(activity_model, "classify")
            self.classifier = self._models.resolve(path, "classify")  # (model, config, classes)
        self.clock0: float | None = None  # the model clock's t = 0 sample, s since the session's t0
        self._next = 0  # clock index of the next window's start
        self.odo = _Odometry()
        self.fuser: IncrementalFuser | None = None
        self._fused: FuseResult | None = None  # the latest
        self._frame = FixFrame()  # the fixes taken (t, east, north, accuracy) and their frame's origin
        self.activity: dict | None = None
        self._activity_at = -np.inf
        self.warnings: list[str] = []
        self._trusted = False
        self.t_s = 0.0
        self.timings: list[float] = []  # seconds per update that changed something (wall clock)
        # and this process's CPU seconds for the same updates: what the update costs, whatever else the machine runs
        self.cpu_timings: list[float] = []
        self._state: dict | None = None
        self._tail = (np.empty(0), np.empty((0, 2)))  # the provisional path after the final one: t, xy
        self._multi = False  # the session has shown several of the model's devices (_several)
        self._seen_s = self._fused_s = -np.inf  # session time of the last update's data, of the last fusion
        self.phase = 0.0  # [0, 1): the session's phase (the buffer's), which offsets its periodic work (_phased)
        # issue 61 §2: the update's Recording from the buffer's arrays where the session's input allows
        # (lean_recording) and its input aligned with every due session's (align_steps); False:
        # the importer's step and align, session by session, as before (the tests compare the two)
        self.batched = True
        self._template: Recording | None = None  # the latest Recording the importer's step made

    # ---- setup -------------------------------------------------------------------------------

    def _start(self, rec) -> bool:
        """Decide the model and the clock once every device starting with the others has started."""
        streams = list(rec.devices.values())
        if not streams:
            return False
        first = min(float(s.t[0]) for s in streams)
        last = max(float(s.t[-1]) for s in streams)
        tol = (odometry_preprocess(self.cfg) if self.cfg is not None else PreprocessConfig()).edge_tolerance
        if last - first <= tol + START_MARGIN_S:
            return False
        if self.model is None:
            # the fixes the walk has by now decide a phone-only walk's default (pretrained.phone_only_choice)
            has_fixes = rec.fixes is not None and len(rec.fixes.t) > 0
            path = pretrained.model_path(self._model_arg, "odometry", tuple(rec.devices), has_fixes)
            self.model, self.cfg = self._models.resolve(path, "odometry")
            self.model_path = path
            # a heading prior only for a phone-only walk (the frame's reference is the phone's)
            fcfg = fuse.config_for(
                path if Path(path).exists() else None, rec.meta, "phone" if set(rec.devices) == {"phone"} else "common"
            )[0]
            self.fuser = IncrementalFuser(fcfg, *self._fuse_lag)
        pcfg = odometry_preprocess(self.cfg)
        if not any(d in rec.devices for d in pcfg.devices):
            return False
        self.clock0 = common_span(rec, pcfg.devices, pcfg.edge_tolerance)[0]
        return True

    # ---- one update --------------------------------------------------------------------------

    def update(self, buf, final: bool = False) -> bool:
        """Process what is new in ``buf`` (a :class:`wearnav.live.buffer.SessionBuffer`) since the
        last call, once ``step_s`` more of the session has arrived; ``final``: the session has ended,
        predict up to its last sample as ``track`` does. True when the path, the fixes or the
        activity changed. :meth:`begin`, the model on the new windows, then :meth:`finish`: a
        :class:`wearnav.live.crowd.Crowd` runs the middle step once for many sessions."""
        step = self.begin(buf, final)
        if step is None:
            return False
        vel = predict_windows(self.model, step.x, step.mask) if step.x is not None else None
        w = self.activity_windows(step)
        act = None if w is None or self.classifier is None else (w, classify_windows(self.classifier[0], [w])[0])
        return self.finish(step, vel, act)

    def begin(self, buf, final: bool = False, batch: bool = False) -> Step | None:
        """The first half of :meth:`update`: the session's new input and its windows (``Step.x``,
        None when no window is due); None when there is nothing to do yet. ``batch``: the input is
        left to align (``Step.job``) for :meth:`align_steps`, which a
        :class:`wearnav.live.crowd.Crowd` runs once for every due session."""
        tic, cpu_tic = time.perf_counter(), time.process_time()
        whole = None
        if self.clock0 is None:
            self.phase = float(getattr(buf, "phase", 0.0))
            tol = (odometry_preprocess(self.cfg) if self.cfg is not None else PreprocessConfig()).edge_tolerance
            if hasattr(buf, "motion_span_s") and buf.motion_span_s() < tol + START_MARGIN_S - 1e-6:
                return None  # too short for _start, whose streams span no more than this: no Recording yet
            whole = buf.recording()  # the session so far (short): the clock's start, and every fix so far
            if not self._start(whole):
                return None
        assert self.clock0 is not None and self.cfg is not None  # set by _start
        covered = float(buf.covered_until())
        if not final and covered - self._seen_s < self.step_s:
            return None
        self._seen_s = covered
        pcfg = odometry_preprocess(self.cfg)
        rate, L = pcfg.rate, self.cfg.window
        g_a = max(0, self._next - self._context(pcfg))  # the first clock sample aligned
        t_from = self.clock0 + g_a / rate
        # a second more than the clock needs: the interpolation's samples before its start
        if whole is not None:
            rec = self._template = whole
        else:
            rec = lean_recording(buf, t_from - 1.0, self._template) if self.batched and self._template else None
            if rec is None:
                rec = self._template = buf.recording(t_from - 1.0)
        if self._radio is not None:
            rec, said = self._radio.join(rec, buf)
            self.warnings += said
        changed = self._take_fixes(rec)
        end = common_span(rec, pcfg.devices, pcfg.edge_tolerance)[1] if final else covered
        g_end = int(np.floor((end - self.clock0) * rate + 1e-9))  # the clock's last sample (align's clock())
        g_last = g_end if final else g_end - int(np.ceil(self.lag_s * rate))  # last sample a window may use
        lag = 0.0 if final else max(self.lag_s, self.frame_lag_s if self._several(rec, pcfg) else 0.0)
        step = Step(tic, final, rec, covered, changed, g_final=g_end - int(np.ceil(lag * rate)), cpu_tic=cpu_tic)
        if g_last - self._next + 1 >= L:
            self._windows(step, pcfg, g_a, g_end, g_last)
            if not batch:
                self.align_steps([(self, step)])
        return step

    def finish(self, step: Step, vel: np.ndarray | None, activity: tuple[Windows, np.ndarray] | None = None) -> bool:
        """The second half of :meth:`update`: the path grown by ``vel`` (N, 2) m/s, the velocities
        of ``step``'s windows; fusion, activity (``activity``: :meth:`activity_windows` of this
        step and the classifier's probabilities of them; None: no label due), warnings, the page's
        state."""
        changed = step.changed
        if step.t_c is not None:
            assert vel is not None and len(vel) == len(step.t_c)  # one velocity per window
            if step.yaw is not None:  # the windows' heading frame back to the world's (as predict_sequence)
                vel = turn(vel, step.yaw)
            changed |= self._grow(step, vel)
        covered, rec, final = step.covered, step.rec, step.final
        if changed and (final or covered - self._fused_s >= FUSE_EVERY_S):
            self._fuse()
            self._fused_s = self._phased(self._fused_s, covered, FUSE_EVERY_S)
        if activity is not None:
            changed |= self._label(*activity, covered)
        if not self._trusted and covered >= TRUST_AFTER_S:
            self.warnings += input_warnings(self.model_path, self.cfg, rec)
            self._trusted, changed = True, True
        self.t_s = max(self.t_s, covered)
        if changed or self._state is None:
            self._state = self._snapshot()  # one assignment: state() may be read from another thread
            self.timings.append(time.perf_counter() - step.tic)
            self.cpu_timings.append(time.process_time() - step.cpu_tic)
        return changed

    def _phased(self, last: float, covered: float, period: float) -> float:
        """When a job done every ``period`` of session time (the smoother's solve, the activity
        label) counts as last done, now that it is done at ``covered``: ``covered``, but the first
        time ``covered`` less the session's phase of a period, so that its second run comes early
        by that much (issue 61: sessions that start together, as a crowd's may, do not all run it
        in one tick)."""
        return covered - (self.phase * period if last == -np.inf else 0.0)

    def _several(self, rec, pcfg) -> bool:
        """Whether the session has shown more than one of the model's devices so far (once it has,
        for good). A model's layout may list more devices than the session has (PDR's lists all
        three and reads the first present): with one present its common frame is that device's own,
        so each window's input is local in time, as with a one-device model."""
        self._multi = self._multi or len(set(rec.devices) & set(pcfg.devices)) > 1
        return self._multi

    def _context(self, pcfg) -> int:
        """Clock samples aligned before the first window not yet final (``CONTEXT_S``;
        ``ONE_DEVICE_CONTEXT_S`` at most while the session has shown one device: :meth:`_several`)."""
        ctx = self.context_s if self._multi else min(self.context_s, ONE_DEVICE_CONTEXT_S)
        return int(round(ctx * pcfg.rate))

    def _windows(self, step: Step, pcfg, g_a: int, g_end: int, g_last: int) -> None:
        """The clock from ``g_a`` (the context) to ``g_end`` to align, and the windows inside
        ``g_last`` to cut from it, as ``step``'s job (:meth:`align_steps`)."""
        assert self.clock0 is not None  # set by _start
        clock = self.clock0 + np.arange(g_a, g_end + 1) / pcfg.rate  # align's clock(): t0 + k / rate
        step.job = (pcfg, clock, g_a, g_last)

    @staticmethod
    def align_steps(work: list[tuple[LiveTracker, Step]]) -> None:
        """Every step's job (:meth:`_windows`) done: the input of all of them aligned at once
        (:func:`wearnav.preprocess.batch.align_many`, ``align``'s output to round-off: one rotation
        and one stacked low-pass for all due sessions, issue 61 §2) and each step's windows cut
        (as :func:`wearnav.evaluate.predict_sequence` cuts them) into it."""
        jobs = [(tr, st) for tr, st in work if st.job is not None]
        if not jobs:
            return
        many = [(tr, st) for tr, st in jobs if tr.batched]
        seqs = align_many([(st.rec, st.job[0], st.job[1]) for _, st in many if st.job is not None])
        for (tr, st), seq in zip(many, seqs):
            tr._cut(st, seq)
        for tr, st in jobs:
            if st.job is not None:  # not batched: align, session by session
                tr._cut(st, align(st.rec, st.job[0], st.job[1]))

    def _cut(self, step: Step, seq: Aligned) -> None:
        """``step``'s windows from its aligned input ``seq``."""
        assert self.cfg is not None and step.job is not None  # set by _start, _windows
        g_a, g_last = step.job[2:]
        step.job = None
        L, S = self.cfg.window, self.cfg.stride
        part = slice(self._next - g_a, g_last - g_a + 1)
        yaw = seq.yaw[part] if seq.yaw is not None else None  # PreprocessConfig.heading_frame
        seq = Aligned(seq.name, seq.t[part], seq.devices, seq.imu[:, part], seq.mask[:, part], None, seq.meta, yaw=yaw)
        wds = WindowDataset([seq], WindowConfig(window=L, stride=S, target=None))
        if len(wds) == 0:
            return
        b = wds[np.arange(len(wds))]
        step.clock_t, step.t_c, step.x, step.mask = seq.t, b["t"].mean(dim=1).numpy(), b["x"], b["mask"]
        step.yaw = b["yaw"].numpy() if "yaw" in b else None

    def _grow(self, step: Step, vel: np.ndarray) -> bool:
        """The windows inside ``step.g_final`` for good (the path and the smoother grow by them),
        the rest as the provisional tail (predicted again at the next update)."""
        assert self.cfg is not None and self.fuser is not None  # set by _start
        assert step.t_c is not None and step.clock_t is not None  # set by _windows
        L, S, t_c = self.cfg.window, self.cfg.stride, step.t_c
        n = int(np.clip((step.g_final - self._next - L + 1) // S + 1, 0, t_c.size))  # windows ending by g_final
        o = self.odo
        if n:
            n_old = len(o.t_c)
            o.t_c += t_c[:n].tolist()
            o.vel += vel[:n].tolist()
            self._next += n * S
            if len(o.t_c) >= 2:
                t, xy = _integrate_on(step.clock_t, o.array("t_c"), o.array("vel"), n_old, o.t, o.xy)
                for ti, p in zip(t, xy):
                    self.fuser.add_odometry(float(ti), p)
                o.t += t.tolist()
                o.xy += xy.tolist()
        self._tail = (np.empty(0), np.empty((0, 2)))
        if n < t_c.size and len(o.t_c) + t_c.size - n >= 2:
            tc = np.concatenate([o.array("t_c"), t_c[n:]]) if o.t_c else t_c[n:]
            v = np.concatenate([o.array("vel"), vel[n:]])
            self._tail = _integrate_on(step.clock_t, tc, v, len(o.t_c), o.t, o.xy)
        return True

    # ---- fixes and fusion ----------------------------------------------------------------------

    @property
    def origin(self) -> tuple[float, float] | None:
        """The session's frame: the first good fix (lat, lon), None until chosen (:class:`FixFrame`)."""
        return self._frame.origin

    @property
    def fixes(self) -> list[tuple[float, float, float, float]]:
        """The fixes taken so far: t, east, north, accuracy."""
        return self._frame.fixes

    def _take_fixes(self, rec) -> bool:
        """The fixes newer than the last taken, into the session's frame and the smoother."""
        rows = self._frame.take(rec, self.fuser.cfg.wide_m if self.fuser else fuse.FuseConfig().wide_m)
        for t, e, n, a in rows:
            assert self.fuser is not None  # set by _start, which comes before any fix is taken
            self.fuser.add_fix(t, e, n, a)
        return bool(rows)

    def _fuse(self) -> None:
        """The smoother's path: the fixed-lag smoother's over the final path, or before there is one
        (a session's first ``frame_lag_s``) the batch smoother's over the provisional path."""
        if not self.fixes:
            self._fused = None
        elif len(self.odo.t) >= 2:
            assert self.fuser is not None  # set by _start, before any fix is taken
            self._fused = self.fuser.result()
        elif len(self._tail[0]) >= 2:
            assert self.fuser is not None
            f = np.asarray(self.fixes)
            self._fused = fuse.smooth(*self._tail, f[:, 0], f[:, 1:3], f[:, 3], self.fuser.cfg)

    # ---- activity ----------------------------------------------------------------------------

    def activity_windows(self, step: Step) -> Windows | None:
        """The windows the activity classifier is to see at ``step`` (:mod:`wearnav.live.activity`): at
        most every ``ACTIVITY_EVERY_S``; None when no label is due. A :class:`wearnav.live.crowd.Crowd`
        runs the classifier once for many sessions' windows (:func:`classify_windows`)."""
        if not self._label_due(step):
            return None
        if self.batched:
            return self.activity_windows_many([(self, step)])[0]
        assert self.classifier is not None  # _label_due
        return label_windows(self.classifier, step.rec, step.covered)

    def _label_due(self, step: Step) -> bool:
        """Whether the activity label is due at ``step`` (at most every ``ACTIVITY_EVERY_S``)."""
        return self.classifier is not None and step.covered - self._activity_at >= ACTIVITY_EVERY_S

    def _activity_job(self, step: Step) -> tuple[tuple, Job] | None:
        """The classifier and what :func:`wearnav.live.activity.label_windows_many` aligns for ``step``;
        None where no label is due or the input is too short for one."""
        if self.classifier is None or not self._label_due(step):
            return None
        job = label_job(self.classifier, step.rec, step.covered)
        return None if job is None else (self.classifier, job)

    @staticmethod
    def activity_windows_many(work: list[tuple[LiveTracker, Step]]) -> list[Windows | None]:
        """:meth:`activity_windows` of every step, their inputs aligned at once
        (:func:`wearnav.live.activity.label_windows_many`, issue 61 §2)."""
        return label_windows_many([tr._activity_job(st) for tr, st in work])

    def _label(self, w: Windows, prob: np.ndarray, covered: float) -> bool:
        """The latest window's activity from the classifier's probabilities ``prob`` of ``w``."""
        assert self.classifier is not None  # w came from activity_windows
        model, _, classes = self.classifier
        t, cls, conf = decide_classes(model, w, prob)
        self._activity_at = self._phased(self._activity_at, covered, ACTIVITY_EVERY_S)
        label = {
            "label": class_name(classes, int(cls[-1])),
            "t_s": round(float(t[-1, 1]), 3),
            "confidence": round(float(conf[-1]), 3),
        }
        if cls[-1] == UNKNOWN_INDEX:  # the page says why (issue 35 §3)
            label["note"] = unknown_note(model, 1, 1).split(": ", 1)[1]
        changed = self.activity is None or label["label"] != self.activity["label"]
        self.activity = label
        return changed

    # ---- what the page shows -----------------------------------------------------------------

    def path(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
        """Every path sample: times (s), east/north (m; the odometry's own frame where not fused),
        1-σ (m, NaN unknown) and what placed it."""
        t = np.concatenate([self.odo.array("t"), self._tail[0]])
        xy = np.concatenate([self.odo.array("xy"), self._tail[1]])
        res = self._fused
        if res is None or res.method == "none" or len(res.xy) < 2:
            return t, xy, np.full(len(t), np.nan), "none"
        n = len(res.xy)
        if n == len(t):
            return t, res.xy, res.sigma_m, res.method
        # the samples since the last solve: placed by the rigid fit of the last PLACE_S smoothed seconds
        k = slice(int(np.searchsorted(t[:n], t[n - 1] - PLACE_S)), n)
        yaw, offset, _ = fuse.rigid_fit(xy[k], res.xy[k], np.ones(k.stop - k.start))
        c, s_ = np.cos(yaw), np.sin(yaw)
        tail = xy[n:] @ np.array([[c, s_], [-s_, c]]) + offset
        return t, np.concatenate([res.xy, tail]), np.concatenate([res.sigma_m, np.full(len(tail), np.nan)]), res.method

    def state(self) -> dict:
        """The JSON-able state the page renders (the live contract), as of the latest update."""
        return self._state if self._state is not None else self._snapshot()

    def _snapshot(self) -> dict:
        t, xy, sig, anchor = self.path()
        res = self._fused if anchor != "none" else None
        settled = len(self.odo.t) if res is None else min(len(res.xy), len(self.odo.t))
        rate = self.cfg.rate if self.cfg is not None else 1.0
        return {
            "origin": list(self.origin) if self.origin is not None else None,
            "path": self._page.path(t, xy, sig, rate, res, settled),
            "anchor": anchor,
            # the path after this time is provisional: predicted again as data arrives (FRAME_LAG_S)
            "final_t_s": round(float(self.odo.t[-1]), 3) if self.odo.t else None,
            "fixes": self._page.fixes(self.fixes),
            "activity": self.activity,
            "plan": self._page.plan(self.origin),
            "warnings": self.warnings
            + (self._fused.warnings if self._fused is not None else [])
            + (
                []
                if self.fixes or self.t_s < TRUST_AFTER_S
                else ["no location fixes yet: the path is not placed on a map"]
            ),
            "t_s": round(float(self.t_s), 3),
        }


def _integrate_on(clock_t: np.ndarray, tc: np.ndarray, v: np.ndarray, n_old: int, t_prev: list, xy_prev: list):
    """The path at the clock's samples after ``t_prev[-1]`` up to the last window centre of ``tc``
    (velocities ``v``; the first ``n_old`` already integrated into ``t_prev``, ``xy_prev``), on from
    the last position (the two centres before it give its velocity), or from (0, 0) at the first
    sample after the first centre where nothing was integrated yet (:func:`wearnav.track.odometry`)."""
    if not t_prev:
        t = path_times(clock_t, tc)
        return t, integrate_velocity(tc, v, t, np.zeros(2))
    k = max(0, n_old - 2)
    t_new = clock_t[(clock_t > t_prev[-1]) & (clock_t <= tc[-1])]
    xy = integrate_velocity(tc[k:], v[k:], np.concatenate([[t_prev[-1]], t_new]), np.asarray(xy_prev[-1]))
    return t_new, xy[1:]


__all__ = ["LiveTracker", "Step", "CONTEXT_S", "LAG_S", "FRAME_LAG_S"]
