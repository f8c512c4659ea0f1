"""GRBL 1.1 real-time overrides: the bytes (config.h CMD_*_OVR_*), their ranges, and the fewest
bytes from one override value to another."""

from __future__ import annotations

import threading
import time

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
OVR_KEYS = {"feed": (0x90, {10: 0x91, -10: 0x92, 1: 0x93, -1: 0x94}, 0),
             "spindle": (0x99, {10: 0x9A, -10: 0x9B, 1: 0x9C, -1: 0x9D}, 2)}  # fmt: skip


def after_override(value: int | None, code: int) -> int | None:
    """The feed or spindle override after byte ``code`` as GRBL computes it (None: unknown)."""
    reset, steps, _ = OVR_KEYS["feed" if code <= 0x94 else "spindle"]
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
    reset, steps, _ = OVR_KEYS[which]
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
                w = after_override(v, code)
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


class OverrideState:
    """What the override bytes written have made of GRBL's feed, rapid and spindle overrides, and
    what it last reported (``Ov:``); any thread, under :attr:`lock`."""

    def __init__(self) -> None:
        self.log: list[tuple[float, int]] = []  # (stream clock s, byte) of every byte written
        self.lock = threading.RLock()
        self.reported: tuple[int, int, int] | None = None
        # what our bytes have made of the feed, rapid and spindle overrides (None: unknown
        # until an Ov: report or a reset; GRBL keeps them from one program to the next)
        self.commanded: list[int | None] = [None, None, None]
        self.written_t = -float("inf")  # perf_counter of the last override byte

    def wrote(self, t: float, code: int) -> None:
        """Byte ``code`` went out at stream time ``t``."""
        with self.lock:
            self.written_t = time.perf_counter()
            self.log.append((t, code))
            if code <= 0x94:
                self.commanded[0] = after_override(self.commanded[0], code)
            elif code <= 0x97:
                self.commanded[1] = {0x95: 100, 0x96: 50, 0x97: 25}[code]
            else:
                self.commanded[2] = after_override(self.commanded[2], code)

    def bytes_to(self, which: str, target: int) -> list[int]:
        """The bytes taking ``which`` (feed or spindle) to ``target`` %, clamped to its range."""
        lo, hi = FEED_OVR_RANGE_PCT if which == "feed" else SPINDLE_OVR_RANGE_PCT
        goal = min(max(int(round(target)), lo), hi)
        with self.lock:
            return override_bytes(self.commanded[OVR_KEYS[which][2]], goal, which)

    def after_reset(self) -> None:
        with self.lock:
            self.commanded = [100, 100, 100]  # main.c: a reset restores the defaults

    def note_report(self, raw: bytes) -> None:
        """An ``Ov:`` field in a status report (reader thread): the reported values; once our
        last byte is ``OVR_SETTLE_S`` old they are what our bytes made (or a panel's change)."""
        i = raw.find(b"|Ov:")
        if i < 0:
            return
        field = raw[i + 4 :].split(b"|")[0].split(b">")[0]
        try:
            f, r, s = (int(v) for v in field.split(b","))
        except ValueError:
            return
        with self.lock:
            self.reported = (f, r, s)
            if time.perf_counter() - self.written_t > OVR_SETTLE_S:
                self.commanded = [f, r, s]
