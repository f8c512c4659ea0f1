"""GRBL's real-time overrides in the simulated controller (protocol_exec_rt_system,
plan_compute_profile_nominal_speed, stepper.c's segment ring). Mixed into
:class:`rig.sim.grbl.SimGrbl`, which owns the state it uses (see its module docstring).
"""

from __future__ import annotations

import math

from planning.nc import DWELL, RAPID
from rig.sim._controller import _Planned
from rig.sim._grbl_state import GrblFields

# config.h: MIN/MAX_FEED_RATE_OVERRIDE, MIN/MAX_SPINDLE_SPEED_OVERRIDE, %
FEED_OVR_MIN, FEED_OVR_MAX, SPINDLE_OVR_MIN, SPINDLE_OVR_MAX = 10, 200, 10, 200
# stepper.c: a step segment is DT_SEGMENT = 1 / ACCELERATION_TICKS_PER_SECOND (100) of motion;
# the segment ring (SEGMENT_BUFFER_SIZE 6) holds 5, the one running and 4 prepared ahead. An
# override recomputes the plan (plan_cycle_reinitialize) and the spindle PWM (STEP_CONTROL_
# UPDATE_SPINDLE_PWM) for the segments prepared from then on: what is already in the ring runs
# at the old values first.
DT_SEGMENT_S = 0.01
SEGMENTS_AHEAD = 4


def overrides_after(code: int, pct: tuple[int, int, int]) -> tuple[int, int, int] | None:
    """The overrides (feed, rapid, spindle), %, after the real-time byte ``code`` (0x90-0x9D),
    within GRBL's limits; None for 0x98 (unused in 1.1h)."""
    f, r, s = pct
    if code == 0x90:
        f = 100
    elif 0x91 <= code <= 0x94:
        f += {0x91: 10, 0x92: -10, 0x93: 1, 0x94: -1}[code]
    elif code <= 0x97:
        r = {0x95: 100, 0x96: 50, 0x97: 25}[code]
    elif code == 0x99:
        s = 100
    elif 0x9A <= code <= 0x9D:
        s += {0x9A: 10, 0x9B: -10, 0x9C: 1, 0x9D: -1}[code]
    else:
        return None
    f = min(max(f, FEED_OVR_MIN), FEED_OVR_MAX)
    s = min(max(s, SPINDLE_OVR_MIN), SPINDLE_OVR_MAX)
    return f, r, s


def first_new_segment_s(now_s: float) -> float:
    """When the first segment prepared after an override at ``now_s`` starts, moving: after the
    running segment and the SEGMENTS_AHEAD already prepared (40-50 ms later)."""
    return (math.floor(now_s / DT_SEGMENT_S + 1e-9) + 1 + SEGMENTS_AHEAD) * DT_SEGMENT_S


class GrblOverridesMixin(GrblFields):
    """Feed, rapid and spindle overrides of SimGrbl: taken at the byte, run at the segment
    boundary after the segments already prepared."""

    # -- overrides (protocol_exec_rt_system, plan_compute_profile_nominal_speed) ---------------
    def _override(self, code: int, t: float) -> None:
        """One override byte arrived at ``t``: the new value within GRBL's limits; a change is
        reported in the next status (``Ov:``) and applied to the segment running (split there)
        and to every one after it (the planner recomputes the blocks it holds)."""
        was = (self.feed_ovr, self.rapid_ovr, self.spindle_ovr)
        pct = overrides_after(code, was)
        if pct is None or pct == was:
            return  # 0x98, or at a limit: nothing changes, nothing is reported
        f, r, s = pct
        now = max(t, self._advanced_t)  # never before what the executor has already run
        self._advance(now)
        self._report.override_changed()  # reported at once
        self.feed_ovr, self.rapid_ovr, self.spindle_ovr = f, r, s
        self._event("override", f"feed {f} %, rapid {r} %, spindle {s} %", now)
        # moving, the segments already prepared run first: the change starts with the first
        # segment prepared after it, SEGMENTS_AHEAD segment times after the running one ends
        # (40-50 ms); idle or held, nothing is prepared and it applies at once
        due = now
        if self._moving() and not self.held and self._hold_stop_at is None:
            due = first_new_segment_s(now)
        self._ovr_due.append((max(due, self._ovr_due[-1][0] if self._ovr_due else due), f, r, s))
        self._advance(now)

    def _apply_override(self, now: float, f: int, r: int, s: int) -> None:
        """The stepper reaches the segments prepared at the new values: the running segment is
        split at ``now`` and goes on at them, the spindle turns at its new speed."""
        f0, r0, _ = self._run_ovr
        self._run_ovr = (f, r, s)
        if (f, r) != (f0, r0):
            self._replan(now)
        rpm = self._spindle_prog * self._rpm_scale()
        if rpm != self._spindle:
            self._spindle = rpm
            for fn in self._spindle_listeners:
                fn(now, rpm)

    def _replan(self, now: float) -> None:
        """The running segment goes on from where it is at its new speed (a hold being carried
        out, or held, takes the new speed when it resumes)."""
        b = self._cur
        if b is None or not len(b.motion) or self.held or self._hold_stop_at is not None:
            return
        if int(b.motion.kind[self._seg_i]) == DWELL or self._seg_t1 <= now:
            return
        run = self._seg_t1 - self._seg_t0
        frac = self._seg_frac0 + (1 - self._seg_frac0) * (now - self._seg_t0) / run
        self.busy_s -= self._seg_t1 - now
        self._start_segment(now, frac)

    def _time_scale(self, b: _Planned, i: int) -> float:
        kind = int(b.motion.kind[i])
        feed_ovr, rapid_ovr, _ = self._run_ovr
        if kind == DWELL:
            return 1.0
        if kind == RAPID:
            return 100.0 / rapid_ovr
        if feed_ovr == 100:
            return 1.0
        v = self._programmed_mm_min(b, i)
        if v <= 0:
            return 1.0
        # the overridden feed stays below the rapid rate (block->rapid_rate)
        return v / min(v * feed_ovr / 100.0, max(self.rapid_mm_min, v))

    def _rpm_scale(self) -> float:
        return self._run_ovr[2] / 100.0

    def _start_block(self, b: _Planned, t0: float) -> None:
        super()._start_block(b, t0)
        if self._cur is b:
            self._spindle_prog = b.spindle_rpm

    def _advance(self, now: float) -> None:
        while self._ovr_due and self._ovr_due[0][0] <= now:
            t_due, f, r, s = self._ovr_due.popleft()
            t_due = max(t_due, self._advanced_t)
            super()._advance(t_due)
            self._advanced_t = max(self._advanced_t, t_due)
            self._apply_override(t_due, f, r, s)
        super()._advance(now)
        self._advanced_t = max(self._advanced_t, now)

    def _next_wake(self, now: float) -> float:
        t = super()._next_wake(now)
        return max(min(t, self._ovr_due[0][0]), now) if self._ovr_due else t
