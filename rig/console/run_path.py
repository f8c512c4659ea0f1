"""A finished run's toolpath for the page's browse mode, from its run file alone: the planned
path (the stored program interpreted with the recorded machine, as the live view draws it) and
the executed path, estimated as the drip feed's DRO is (a run file holds no positions): each
executed block's segments at the program's feeds from the block's recorded execution start,
squeezed to end before the next block started (the controller had finished it by then), the
last one cut off where the run ended; the tool stands still through the feed holds the run
recorded (a pause event to the next resume, or to the end). Each point carries the feed and the
force there.

A point is ``[t_s, x_mm, y_mm, z_mm, feed_mm_min, force_n]`` as in :mod:`rig.console.trail`;
force: the mean resultant of the run file's calibrated forces since the point before (None
without a calibration).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from analysis.runs import file as rf
from rig.console.program_path import ProgramPath
from rig.console.results import RunToolpath

STEP_S = 0.1  # a point at least this often along a segment (the live path samples at 0.08 s)
MAX_POINTS = 20_000  # then every other point is dropped, as the live path does
MAX_SEGMENTS = 5000  # the planned path, as the live view gets it


def run_toolpath(path: Path) -> RunToolpath:
    """``{"toolpath": planned segments, "trail": executed points, "source": how}`` of the run
    file at ``path`` (``toolpath`` as :meth:`ProgramPath.toolpath`); a program that cannot be
    interpreted gives empty paths and the reason in ``source``."""
    run = rf.load_run(path, repair=False)
    name = str(run.program_info.get("name") or path.stem)
    machine, machine_note = _machine(run.rig.get("machine"))
    try:
        pp = ProgramPath(run.program_text, machine, name)
    except Exception as exc:  # noqa: BLE001 - the rest of the run is still shown
        return {"toolpath": [], "trail": [], "source": f"the program's path is not shown: "
                f"{str(exc).splitlines()[0][:200]}"}  # fmt: skip
    trail = _executed(pp, run)
    return {"toolpath": pp.toolpath(MAX_SEGMENTS), "trail": trail,
            "source": "estimated from the block table's execution starts and the program "
            f"(at its feeds, no acceleration){machine_note}"}  # fmt: skip


def _machine(name: Any) -> tuple[Any, str]:
    """The recorded machine's config (its dialect, arc tolerance, reference points), else none."""
    if not name:
        return None, "; the run names no machine: interpreted without one"
    from analysis.config import load_machine

    try:
        return load_machine(str(name)), ""
    except Exception as exc:  # noqa: BLE001 - a machine file gone since: still a path
        return None, f"; machine {name!r} not found ({str(exc).splitlines()[0][:120]})"


def _executed(pp: ProgramPath, run: rf.Run) -> list[list[float | None]]:
    """The executed points (see the module docstring), in time order."""
    b = run.blocks
    ok = np.isfinite(b["exec_s"].to_numpy(float))
    clock = _HoldClock(run)
    # on the clock that stops in a hold: the estimate runs at the program's feeds on it
    starts = sorted(zip(clock.moving(b["exec_s"].to_numpy(float)[ok]).tolist(),
                        b["block"].to_numpy(int)[ok].tolist()))  # fmt: skip
    t_end = run.t0_s + run.duration_s if math.isfinite(run.t0_s) else math.inf
    t_end = float(clock.moving(np.array([t_end]))[0]) if math.isfinite(t_end) else t_end
    forces = _Forces(run, clock)
    points: list[list[float | None]] = []
    for k, (t0, block) in enumerate(starts):
        idx = pp.by_block.get(int(block))
        if not idx or t0 >= t_end:
            continue
        last = k == len(starts) - 1
        t_next = t_end if last else min(starts[k + 1][0], t_end)
        total = float(sum(pp.dur_s[i] for i in idx))
        # done before the next block started: squeezed into its time; the last one: cut off
        squeeze = 1.0 if last or total <= t_next - t0 else (t_next - t0) / total
        t = t0
        for i in idx:
            t = _segment(pp, i, t, squeeze, t_next, points, forces)
            if t >= t_next:
                break
    if len(points) > MAX_POINTS:
        points = points[:: -(-len(points) // MAX_POINTS)]
    return points


class _HoldClock:
    """The run clock without the run's feed holds (a pause event to the next resume, or to the
    end): ``moving`` maps run-clock times onto it, ``run`` maps back (a hold's start, for a time
    the tool stood at)."""

    def __init__(self, run: rf.Run) -> None:
        holds: list[tuple[float, float]] = []
        t_hold = None
        ev = run.events
        for kind, t in zip(ev["kind"], ev["time_s"].to_numpy(float)):
            if kind == rf.EV_PAUSE and t_hold is None and math.isfinite(t):
                t_hold = float(t)
            elif kind == rf.EV_RESUME and t_hold is not None and t >= t_hold:
                holds.append((t_hold, float(t)))
                t_hold = None
        if t_hold is not None:
            holds.append((t_hold, math.inf))
        self.start = np.array([a for a, _ in holds])
        self.held_before = np.concatenate([[0.0], np.cumsum([b - a for a, b in holds])])
        self.start_moving = self.start - self.held_before[:-1]  # each hold's start on this clock

    def moving(self, t: np.ndarray) -> np.ndarray:
        if not len(self.start):
            return t
        k = np.searchsorted(self.start, t, side="right")  # holds begun by t
        i = np.maximum(k - 1, 0)  # the last one begun (where k > 0)
        inside = np.minimum(t - self.start[i], np.diff(self.held_before)[i])
        moved: np.ndarray = t - self.held_before[i] - np.where(k > 0, inside, 0.0)
        return moved

    def run(self, m: float) -> float:
        if not len(self.start):
            return m
        k = int(np.searchsorted(self.start_moving, m, side="left"))  # holds wholly before m
        return float(m + self.held_before[k])


def _segment(pp: ProgramPath, i: int, t0: float, squeeze: float, t_stop: float,
             points: list[list[float | None]], forces: _Forces) -> float:  # fmt: skip
    """Segment ``i`` from run clock ``t0``: its points added (every STEP_S at most, up to
    ``t_stop``); returns the run clock at its end."""
    m = pp.motion
    if m.kind[i] == 4:  # a dwell: no motion
        return t0 + float(pp.dur_s[i]) * squeeze
    a, e = m.start[i, :3].astype(float), m.end[i, :3].astype(float)
    d_s = float(pp.dur_s[i]) * squeeze
    feed = float(m.feed_mm_min[i]) if m.kind[i] != 0 else pp.rapid_mm_min
    if not points or float(points[-1][0] or 0.0) < round(forces.clock.run(t0), 3):  # (it waited)
        _add(points, t0, a, feed, forces)
    if d_s <= 0:
        if _mm(e) != points[-1][1:4]:
            _add(points, t0, e, feed, forces)
        return t0
    n = math.ceil(d_s / STEP_S)
    for j in range(1, n + 1):
        f = j / n
        t = t0 + f * d_s
        if t > t_stop:  # the run ended inside it: where the tool was then
            f, t = (t_stop - t0) / d_s, t_stop
        _add(points, t, a + f * (e - a), feed, forces)  # arcs along the chord, as the DRO
        if t >= t_stop:
            break
    return t0 + d_s


def _add(points: list[list[float | None]], t: float, p: np.ndarray, feed: float,
         forces: _Forces) -> None:  # fmt: skip
    """A point at run clock ``t``, its force over the time since the point before (none first)."""
    t_ms = round(forces.clock.run(t), 3)  # the force over the time stated, on the run clock
    force = forces.mean(float(points[-1][0]), t_ms) if points else None  # type: ignore[arg-type]
    points.append([t_ms, *_mm(p), round(feed, 1), force])


def _mm(p: np.ndarray) -> list[float]:
    return [round(float(v), 3) for v in p]


class _Forces:
    """Mean resultant force between two run-clock times, from the run file's samples."""

    def __init__(self, run: rf.Run, clock: _HoldClock) -> None:
        self.clock = clock  # the points' times are on the clock without holds
        self.t = np.asarray(run.time_s, float)
        f = run.force_n
        self.resultant = None if f is None else np.sqrt((np.asarray(f, float) ** 2).sum(axis=1))

    def mean(self, t0: float, t1: float) -> float | None:
        if self.resultant is None or len(self.t) == 0:
            return None
        a, b = np.searchsorted(self.t, [t0, t1], side="right")
        if b <= a:  # shorter than a sample: the one at t1
            a, b = max(0, b - 1), max(1, b)
        v = self.resultant[a:b]
        return round(float(v.mean()), 1) if len(v) else None
