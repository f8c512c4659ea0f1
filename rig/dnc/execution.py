"""Which block the controller is executing, not only which it acknowledged.

GRBL answers ``ok`` when a line is *planned*: with 15 planner blocks the acknowledged line runs
13 to 17 lines ahead of the one the machine is cutting. :class:`ExecTracker` follows the executing
line from the status reports:

* the position (``MPos`` less the last ``WCO``, or ``WPos``) against the path each sent line
  makes (``planning.nc``'s interpreter run over the lines as sent, from the position GRBL reported
  before the first one): the first line at or after the current one whose path passes within
  ``tol_mm`` of the position is executing; lines without motion (M3, F, ...) in between count as
  done when a later one runs;
* the planner count ``Bf`` when GRBL reports it (``$10`` with the buffer bit): the lines still
  holding planner blocks, counted back from the last acknowledged one, bound the search (the
  executing line is the oldest of them or the one before, whose last segments may already have
  left the planner), which also tells apart passes over the same path;
* Idle with nothing in the planner: every acknowledged line has run.

:class:`TimedTracker` does the same for a drip feed, which reports nothing: the executing block is
the one whose predicted start (planning.nc's time model from the first block on, no acceleration)
has passed, never beyond the last block fully sent.

Start times of execution are kept per line (:attr:`ExecTracker.started`): the time of the first
report that saw the line executing (or past it); lines that ran between two reports get times
interpolated by their predicted durations, skipping the time GRBL reported itself held
(:meth:`ExecTracker.hold`: no line starts, none runs on, while it stands in a feed hold).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from planning.nc import ARC_CCW, ARC_CW, DWELL, Interpreter, Motion, NCError, linearize
from planning.nc import segment_time_s as _segment_time_s

#: mm: a reported position this close to a line's path is on it (GRBL reports 3 decimals, arcs run
#: as chords within $12 = 0.002 mm)
TOL_MM = 0.01


@dataclass
class LinePath:
    """One sent line's motion: polyline points (k, 3) in the work frame (k = 0: no motion),
    its predicted duration, s, and its end point (None: no motion)."""

    points: np.ndarray
    duration_s: float

    @property
    def moves(self) -> bool:
        return len(self.points) >= 2

    @property
    def end(self) -> np.ndarray | None:
        return self.points[-1] if len(self.points) else None


def line_paths(
    texts: Sequence[str],
    start_mm: Sequence[float] = (0.0, 0.0, 0.0),
    *,
    dialect: str = "grbl",
    rapid_mm_min: float = 5000.0,
    machine: object = None,
) -> list[LinePath]:
    """The path of each line of ``texts`` run in order from ``start_mm`` (a line the interpreter
    refuses gets no path; the others go on from the state before it)."""
    it = Interpreter(machine, strict=False, dialect=dialect)
    it.state.position_mm = tuple(float(c) for c in start_mm)
    out = []
    for k, t in enumerate(texts):
        if t.lstrip().startswith("$"):
            out.append(LinePath(np.zeros((0, 3)), 0.0))
            continue
        try:
            m = it.execute(t, block=k)
        except NCError:
            out.append(LinePath(np.zeros((0, 3)), 0.0))
            continue
        out.append(_path_of(m, rapid_mm_min))
    return out


def _path_of(m: Motion, rapid_mm_min: float) -> LinePath:
    if len(m) == 0:
        return LinePath(np.zeros((0, 3)), 0.0)
    dur = float(np.nansum(_segment_time_s(m, rapid_mm_min=rapid_mm_min)))
    kinds = np.asarray(m.kind)
    if (kinds == DWELL).all():
        return LinePath(np.zeros((0, 3)), dur)
    pts: list[np.ndarray] = []
    if ((kinds == ARC_CW) | (kinds == ARC_CCW)).any():
        lin = linearize(m, chord_tol_mm=0.002)
        lm = lin.motion if hasattr(lin, "motion") else lin
        starts, ends, kk = np.asarray(lm.start), np.asarray(lm.end), np.asarray(lm.kind)
    else:
        starts, ends, kk = np.asarray(m.start), np.asarray(m.end), kinds
    for s, e, k in zip(starts, ends, kk):
        if k == DWELL:
            continue
        if not pts or np.any(np.abs(pts[-1] - s) > 1e-9):
            pts.append(np.asarray(s, float))
        pts.append(np.asarray(e, float))
    p = np.array(pts) if pts else np.zeros((0, 3))
    if len(p) >= 2 and np.allclose(p, p[0]):
        p = p[:1]  # no travel
    return LinePath(p, dur)


def distance_to_path(p: np.ndarray, pts: np.ndarray) -> float:
    """Distance, mm, from point ``p`` to the polyline ``pts`` (inf when it has no segment)."""
    return locate_on_path(p, pts)[0]


def locate_on_path(p: np.ndarray, pts: np.ndarray) -> tuple[float, float]:
    """(distance, mm, from ``p`` to the polyline ``pts``; fraction of the polyline's length
    before the nearest point). (inf, 0) when it has no segment."""
    if len(pts) < 2:
        return math.inf, 0.0
    a, b = pts[:-1], pts[1:]
    ab = b - a
    ll = np.einsum("ij,ij->i", ab, ab)
    t = np.where(ll > 0, np.einsum("ij,ij->i", p - a, ab) / np.where(ll > 0, ll, 1.0), 0.0)
    t = np.clip(t, 0.0, 1.0)
    q = a + ab * t[:, None]
    d = np.linalg.norm(q - p, axis=1)
    i = int(np.argmin(d))
    seg = np.sqrt(ll)
    total = float(seg.sum())
    before = float(seg[:i].sum() + seg[i] * t[i])
    return float(d[i]), (before / total if total > 0 else 0.0)


class ExecTracker:
    """Follow the executing line of a GRBL stream (see the module docstring).

    paths : one :class:`LinePath` per sent line (the stream's order)
    planner_blocks : planner blocks each line takes (None: no Bf bound)
    planner_capacity : GRBL's planner size (Bf when empty; None: unknown)
    """

    def __init__(
        self,
        paths: Sequence[LinePath],
        planner_blocks: Sequence[int] | None = None,
        planner_capacity: int | None = None,
        tol_mm: float = TOL_MM,
    ) -> None:
        self.paths = list(paths)
        self.blocks = list(planner_blocks) if planner_blocks is not None else None
        self.capacity = planner_capacity
        self.tol_mm = tol_mm
        self.current = -1  # index of the line executing (-1: none yet)
        self.done = -1  # index of the last line known executed to its end
        self.started: dict[int, float] = {}
        self._new: dict[int, float] = {}
        self._t_last: float | None = None
        self._t_origin: float | None = None
        self.pauses: list[list[float]] = []  # [t0, t1]: GRBL held, nothing ran (in order)

    def hold(self, t0: float, t1: float) -> None:
        """GRBL was held from ``t0`` to ``t1`` (a hold reported from t0 is extended to t1)."""
        if self.pauses and self.pauses[-1][0] == t0:
            self.pauses[-1][1] = max(self.pauses[-1][1], t1)
        elif t1 >= t0:
            self.pauses.append([t0, t1])

    def _after(self, t: float, run_s: float) -> float:
        """The time ``run_s`` of motion after ``t``, the holds skipped."""
        for a, b in self.pauses:
            if b <= t:
                continue
            if a <= t:
                t = b
                continue
            if a - t >= run_s:
                break
            run_s -= a - t
            t = b
        return t + run_s

    def _before(self, t: float, run_s: float) -> float:
        """The time ``run_s`` of motion before ``t``, the holds skipped."""
        for a, b in reversed(self.pauses):
            if a >= t:
                continue
            if b >= t:
                t = a
                continue
            if t - b >= run_s:
                break
            run_s -= t - b
            t = a
        return t - run_s

    def _running(self, t0: float, t1: float) -> float:
        """Motion time between ``t0`` and ``t1``: the holds left out."""
        held = sum(max(0.0, min(b, t1) - max(a, t0)) for a, b in self.pauses)
        return max(0.0, t1 - t0 - held)

    def pop_started(self) -> dict[int, float]:
        """Execution starts found since the last call (line index -> s)."""
        out, self._new = self._new, {}
        return out

    # -- updates -------------------------------------------------------------------------------
    def set_origin(self, t: float) -> None:
        """The earliest time the first line can have started (its acknowledgement)."""
        if self._t_origin is None:
            self._t_origin = t

    def update(
        self,
        t: float,
        state: str,
        pos_mm: Sequence[float] | None,
        acked: int,
        planner_free: int | None = None,
        sent: int | None = None,
    ) -> int:
        """A status report at time ``t`` (the stream's clock): ``acked`` = index of the last line
        answered ok, ``sent`` of the last line written (the one GRBL may be planning); returns
        the executing line (-1 none)."""
        hi = acked if sent is None else min(sent, acked + 1)
        lo = max(self.current, 0)
        busy = None
        if self.blocks is not None and planner_free is not None and self.capacity:
            busy = self.capacity - planner_free
        if state == "Idle" and (busy is None or busy <= 0):
            # nothing in the planner: every acknowledged line has run
            if acked >= 0:
                self._advance_to(acked, t, finished=True)
            return self.current
        if busy is not None and busy > 0 and acked >= 0:
            oldest = self._oldest_in_planner(acked, busy)
            lo = max(lo, oldest - 1)
            hi = min(hi, max(oldest, lo))
        if pos_mm is None or hi < 0:
            return self.current
        p = np.asarray(pos_mm, float)
        for j in range(lo, hi + 1):
            if j >= len(self.paths):
                break
            path = self.paths[j]
            if not path.moves:
                continue
            d, frac = locate_on_path(p, path.points)
            if d <= self.tol_mm:
                if j > self.current:
                    self._advance_to(j, t, frac=frac)
                break
        else:
            if busy is not None and lo > self.current:
                self._advance_to(lo, t, frac=0.0)
        return self.current

    def _oldest_in_planner(self, acked: int, busy: int) -> int:
        assert self.blocks is not None
        n = 0
        j = min(acked, len(self.blocks) - 1)
        while j >= 0:
            n += max(self.blocks[j], 0)
            if n >= busy:
                return j
            j -= 1
        return 0

    def _advance_to(self, j: int, t: float, finished: bool = False, frac: float = 0.0) -> None:
        """Lines up to ``j`` have started by time ``t`` (``finished``: and ended; else ``frac``
        of line ``j``'s path is behind the tool). Start times of the lines not seen executing:
        back to back after the last one seen, at their predicted durations, squeezed into the
        time there was."""
        j = min(j, len(self.paths) - 1)
        new = [k for k in range(max(self.current, -1) + 1, j + 1) if k not in self.started]
        if new:
            dur = [max(self.paths[k].duration_s, 0.0) for k in range(len(self.paths))]
            prev = self.current
            if prev >= 0 and prev in self.started:
                tc = self._after(self.started[prev], dur[prev])
            else:
                tc = self._t_origin if self._t_origin is not None else t
            tc = min(tc, t)
            if finished:
                starts = []
                for k in new:
                    starts.append(min(self._after(tc, 0.0), t))
                    tc = self._after(tc, dur[k])
            else:
                s_j = max(self._before(t, frac * dur[j]), tc)
                before = new[:-1]
                need = sum(dur[k] for k in before)
                room = self._running(tc, s_j)
                scale = min(1.0, room / need) if need > 0 else 0.0
                starts = []
                for k in before:
                    starts.append(min(self._after(tc, 0.0), s_j))
                    tc = self._after(tc, dur[k] * scale)
                starts.append(s_j)
            for k, s0 in zip(new, starts):
                self.started[k] = self._new[k] = float(s0)
        if j > self.current:
            self.done = max(self.done, j - 1)
        self.current = max(self.current, j)
        if finished:
            self.done = max(self.done, j)
        self._t_last = t

    def finish_all(self, j: int, t: float) -> None:
        """GRBL is Idle with empty buffers: lines up to ``j`` have run."""
        if j >= 0:
            self._advance_to(j, t, finished=True)

    def line_ending_at(self, pos_mm: Sequence[float], candidates: Sequence[int]) -> int:
        """The last of ``candidates`` (line indices) with motion whose end is the position, -1."""
        p = np.asarray(pos_mm, float)
        for j in sorted(candidates, reverse=True):
            path = self.paths[j] if 0 <= j < len(self.paths) else None
            if path is not None and path.end is not None and len(path.points) >= 1:
                if path.moves or len(path.points) == 1:
                    return j if np.linalg.norm(path.end - p) <= self.tol_mm else -1
        return -1


class TimedTracker:
    """The executing line of a drip feed, from predicted durations (see the module docstring).

    durations_s : predicted duration of each sent line (planning.nc's time model). A line starts
    when the one before it has ended, or when it has arrived if the control waited for it (a
    starved control): ``start_k = max(end_(k-1), arrival_k)``.
    """

    def __init__(self, durations_s: Sequence[float]) -> None:
        self.dur = [max(float(d), 0.0) for d in durations_s]
        self.current = -1
        self.done = -1
        self.started: dict[int, float] = {}
        self._new: dict[int, float] = {}
        self._end = -math.inf

    def pop_started(self) -> dict[int, float]:
        """Execution starts predicted since the last call (line index -> s)."""
        out, self._new = self._new, {}
        return out

    def arrived(self, k: int, t: float) -> None:
        """Line ``k`` has fully arrived at the control at time ``t``."""
        if k in self.started or not 0 <= k < len(self.dur):
            return
        s0 = max(self._end, t)
        self.started[k] = self._new[k] = s0
        self._end = s0 + self.dur[k]

    def update(self, t: float) -> int:
        """The line executing at time ``t`` (-1 none yet); ``done`` the last one ended."""
        for k in range(max(self.current, 0), len(self.dur)):
            s0 = self.started.get(k)
            if s0 is None or s0 > t:
                break
            self.current = k
            if s0 + self.dur[k] <= t:
                self.done = max(self.done, k)
        return self.current
