"""GRBL 1.1 real-time overrides: the bytes (config.h CMD_*_OVR_*), their ranges, and the fewest
bytes from one override value to another."""

from __future__ import annotations

#: GRBL 1.1 real-time override bytes (config.h CMD_*_OVR_*) and what each does
OVERRIDE_BYTES = {
    0x90: "feed 100 %", 0x91: "feed +10 %", 0x92: "feed -10 %", 0x93: "feed +1 %",
    0x94: "feed -1 %", 0x95: "rapid 100 %", 0x96: "rapid 50 %", 0x97: "rapid 25 %",
    0x99: "spindle 100 %", 0x9A: "spindle +10 %", 0x9B: "spindle -10 %", 0x9C: "spindle +1 %",
    0x9D: "spindle -1 %",
}  # fmt: skip
#: config.h MIN/MAX_FEED_RATE_OVERRIDE and MIN/MAX_SPINDLE_SPEED_OVERRIDE, %
FEED_OVR_RANGE_PCT = SPINDLE_OVR_RANGE_PCT = (10, 200)
#: an Ov: report this long (wall s) after our last override byte shows all our bytes applied
OVR_SETTLE_S = 0.25
# (reset byte, {step: byte}, index in Ov:) per override
_OVR_KEYS = {"feed": (0x90, {10: 0x91, -10: 0x92, 1: 0x93, -1: 0x94}, 0),
             "spindle": (0x99, {10: 0x9A, -10: 0x9B, 1: 0x9C, -1: 0x9D}, 2)}  # fmt: skip


def _after_override(value: int | None, code: int) -> int | None:
    """The feed or spindle override after byte ``code`` as GRBL computes it (None: unknown)."""
    reset, steps, _ = _OVR_KEYS["feed" if code <= 0x94 else "spindle"]
    if code == reset:
        return 100
    if value is None:
        return None
    step = next(k for k, v in steps.items() if v == code)
    lo, hi = FEED_OVR_RANGE_PCT if code <= 0x94 else SPINDLE_OVR_RANGE_PCT
    return min(max(value + step, lo), hi)


def override_bytes(current: int | None, target: int, which: str = "feed") -> list[int]:
    """The fewest override bytes taking GRBL's ``which`` override (feed or spindle) from
    ``current`` % (None: unknown, so the reset first) to ``target`` % (within 10-200 %): a
    breadth-first search over +-10, +-1 and the reset, with GRBL's clamping at the limits."""
    reset, steps, _ = _OVR_KEYS[which]
    lo, hi = FEED_OVR_RANGE_PCT if which == "feed" else SPINDLE_OVR_RANGE_PCT
    if not lo <= target <= hi:
        raise ValueError(f"{which} override {target} %: expected {lo}..{hi} %")
    if current is None:
        return [reset, *override_bytes(100, target, which)]
    prev: dict[int, tuple[int, int]] = {}
    frontier, seen = [current], {current}
    while target not in seen:
        nxt = []
        for v in frontier:
            for code in (*steps.values(), reset):
                w = _after_override(v, code)
                assert w is not None
                if w not in seen:
                    seen.add(w)
                    prev[w] = (v, code)
                    nxt.append(w)
        frontier = nxt
    out: list[int] = []
    v = target
    while v != current:
        v, code = prev[v]
        out.append(code)
    return out[::-1]
