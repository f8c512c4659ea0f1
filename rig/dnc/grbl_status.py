"""GRBL 1.1 status reports (report.c's ``<State|MPos:...|Bf:...|FS:...|Ln:...>``) parsed."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rig.dnc.errors import DncError


@dataclass(frozen=True)
class GrblStatus:
    """A parsed status report. Missing fields are None.

    state : Idle, Run, Hold, Jog, Alarm, Door, Check, Home, Sleep; substate : the ``:n`` of
    ``Hold:0`` / ``Door:1`` ("" if none); mpos_mm / wpos_mm : one of them per report ($10);
    wco_mm : work coordinate offset (sent every 10-30 reports); planner_free, rx_free : Bf;
    line : Ln; feed_mm_min, spindle_rpm : FS (or F); overrides : Ov (feed, rapid, spindle %);
    pins : Pn letters; accessories : A letters
    """

    state: str
    mpos_mm: tuple[float, float, float] | None = None
    planner_free: int | None = None
    rx_free: int | None = None
    feed_mm_min: float | None = None
    spindle_rpm: float | None = None
    line: int | None = None
    substate: str = ""
    wpos_mm: tuple[float, float, float] | None = None
    wco_mm: tuple[float, float, float] | None = None
    overrides: tuple[int, ...] | None = None
    pins: str = ""
    accessories: str = ""

    @property
    def full_state(self) -> str:
        return f"{self.state}:{self.substate}" if self.substate else self.state


def _xyz(nums: list[str]) -> tuple[float, float, float]:
    return (float(nums[0]), float(nums[1]), float(nums[2]))


def parse_status(text: str) -> GrblStatus:
    """``<Run|MPos:1.000,2.000,0.000|Bf:12,100|FS:600,10000|Ln:42>`` -> GrblStatus (report.c's
    fields, any order; unknown fields are ignored)."""
    body = text.strip().removeprefix("<").removesuffix(">")
    parts = body.split("|")
    if not parts or not parts[0]:
        raise DncError(f"GRBL status report {text!r}: no state")
    state, _, sub = parts[0].partition(":")
    kw: dict[str, Any] = {"state": state, "substate": sub}  # GrblStatus's fields, as parsed
    for p in parts[1:]:
        key, _, val = p.partition(":")
        nums = val.split(",")
        try:
            if key == "MPos" and len(nums) >= 3:
                kw["mpos_mm"] = _xyz(nums)
            elif key == "WPos" and len(nums) >= 3:
                kw["wpos_mm"] = _xyz(nums)
            elif key == "WCO" and len(nums) >= 3:
                kw["wco_mm"] = _xyz(nums)
            elif key == "Bf" and len(nums) == 2:
                kw["planner_free"], kw["rx_free"] = int(nums[0]), int(nums[1])
            elif key == "FS" and len(nums) == 2:
                kw["feed_mm_min"], kw["spindle_rpm"] = float(nums[0]), float(nums[1])
            elif key == "F" and len(nums) == 1:
                kw["feed_mm_min"] = float(nums[0])
            elif key == "Ln":
                kw["line"] = int(val)
            elif key == "Ov":
                kw["overrides"] = tuple(int(v) for v in nums)
            elif key == "Pn":
                kw["pins"] = val
            elif key == "A":
                kw["accessories"] = val
        except ValueError:
            raise DncError(f"GRBL status report {text!r}: bad field {p!r}") from None
    return GrblStatus(**kw)
