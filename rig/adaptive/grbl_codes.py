"""GRBL 1.1's real-time override bytes: the fewest that take an override from one % to another
(feed 0x90 reset, 0x91/0x92 +-10 %, 0x93/0x94 +-1 %; the spindle's the same moved by 9),
with the firmware's arithmetic (protocol.c: each step clamps to 10-200 %)."""

from __future__ import annotations

import functools

#: GRBL 1.1 override limits (config.h: MIN/MAX_FEED_RATE_OVERRIDE, ..._SPINDLE_...), %
MIN_PCT, MAX_PCT = 10, 200
#: s from an override byte to the motion running at it: GRBL 1.1h applies a change to the step
#: segments prepared after it (planner.c plan_cycle_reinitialize; the spindle's PWM with
#: STEP_CONTROL_UPDATE_SPINDLE_PWM), behind the ring's segments already prepared (stepper.c:
#: SEGMENT_BUFFER_SIZE 6, the running one and 4 more, DT_SEGMENT 10 ms each): up to 50 ms, then
#: its acceleration ramp ($120-$122) and, for the spindle, the drive's own
APPLY_DELAY_S = 0.05


def _apply(pct: int, code: int, plus10: int, plus1: int, reset: int) -> int:
    """GRBL 1.1's arithmetic for one override byte (protocol.c: each step clamps to 10-200 %)."""
    if code == reset:
        return 100
    step = {plus10: 10, plus10 + 1: -10, plus1: 1, plus1 + 1: -1}[code]
    return min(MAX_PCT, max(MIN_PCT, pct + step))


@functools.lru_cache(maxsize=256)
def _paths_from(cur: int) -> dict[int, tuple[int, ...]]:
    """Breadth-first over GRBL's five feed bytes (reset, +-10, +-1) from ``cur`` %: the fewest
    bytes to every reachable %. Clamping counts (12 -> 18 is -10 (10 %), +10, -1, -1)."""
    best: dict[int, tuple[int, ...]] = {cur: ()}
    frontier = [cur]
    while frontier:
        nxt = []
        for p in frontier:
            for code in (0x90, 0x91, 0x92, 0x93, 0x94):
                q = _apply(p, code, 0x91, 0x93, 0x90)
                if q not in best:
                    best[q] = best[p] + (code,)
                    nxt.append(q)
        frontier = nxt
    return best


def _steps(cur: int, target: int, plus10: int, plus1: int, reset: int) -> list[int]:
    """The fewest override bytes from ``cur`` to ``target`` % (feed codes mapped to the
    spindle's when ``reset`` is the spindle's)."""
    del plus10, plus1  # the spindle's codes are the feed's moved by 9
    path = _paths_from(int(cur))[int(target)]
    shift = reset - 0x90
    return [c + shift for c in path]  # spindle: 0x99-0x9D, the feed's 0x90-0x94 + 9


def feed_codes(cur: int, target: int) -> list[int]:
    return [] if cur == target else _steps(cur, target, 0x91, 0x93, 0x90)


def spindle_codes(cur: int, target: int) -> list[int]:
    return [] if cur == target else _steps(cur, target, 0x9A, 0x9C, 0x99)
