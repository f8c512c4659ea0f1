"""The lobes' chatter frequency and the stability margin on the page, beside the spectrum's
detected peak.

- Campaign side, once per run (:func:`stability_case`): the run's cut as the lobes see it
  (:func:`rig.adaptive.cut.lobe_cut`, as the adaptive controller's pockets: the tool's modes,
  the material's end-mill coefficients, teeth, immersion; and the depth), put in the run info;
  or why there are no lobes. Nothing is computed there: the campaign
  process keeps its time for the logger.
- Server side (:class:`StabilityAt`): the lobes at the current spindle speed
  (:func:`analysis.stability.stability_lobes`, semi-discretization, 0.3-0.9 s a speed) in a
  background thread, again when the speed moves by more than :data:`RPM_STEP_REL`; the page
  gets the predicted chatter frequency, the limiting depth at this speed and the run's depth.
- The detected peak (:func:`detected_peak`): the strongest frequency away from the spindle
  harmonics in the spectrum's window, with the energy off them, as the chatter detector judges
  a stretch (:func:`analysis.chatter.indicators`).
"""

from __future__ import annotations

import math
import threading
from typing import TYPE_CHECKING, cast

import numpy as np

from rig.console.results import CutCase, LobesAt, Margin, Peak

if TYPE_CHECKING:
    from rig.campaign.config import Campaign, RunConditions

#: the lobes are recomputed when the spindle speed moves by more than this (a 1 % move shifts a
#: lobe's flank by about as much; the computation costs 0.3-0.9 s of CPU)
RPM_STEP_REL = 0.01


def stability_case(campaign: Campaign, test: RunConditions) -> CutCase:
    """The run's cut for the lobes as JSON (:func:`rig.adaptive.cut.lobe_cut`), or
    ``{"reason": ...}`` when there are none."""
    from rig.adaptive.cut import lobe_cut

    cut = lobe_cut(campaign, test)
    if isinstance(cut, str):
        return {"reason": cut}
    return {
        "teeth": cut.teeth,
        "milling": "down",
        "radial_immersion": cut.radial_immersion,
        "kt_n_m2": cut.kt_n_m2,
        "kn_n_m2": cut.kn_n_m2,
        "modes": [list(m) for m in cut.modes],
        "depth_mm": float(test.depth_mm),
        "spindle_rpm": abs(float(test.spindle_rpm)),
    }


def lobes_at(case: CutCase, rpm: float) -> LobesAt:
    """The limiting depth (mm; None: stable at every depth searched), chatter frequency (Hz)
    and kind of instability of ``case`` at ``rpm``."""
    from analysis.stability import endmill_case, stability_lobes

    # the ring's JSON keeps each mode as a list [axis, Hz, damping, N/m]: endmill_case unzips it
    modes = cast("list[tuple[str, float, float, float]]", case["modes"])
    sc = endmill_case(modes, case["kt_n_m2"], case["kn_n_m2"], case["teeth"],
                      case["radial_immersion"], [rpm], "console")  # fmt: skip
    lobes = stability_lobes(sc, "sd")
    limit, hz = float(lobes.depth_limit_mm[0]), float(lobes.chatter_hz[0])
    return {"rpm": round(rpm, 1), "depth_limit_mm": round(limit, 4) if math.isfinite(limit)
            else None, "predicted_hz": round(hz, 1) if math.isfinite(hz) else None,
            "kind": lobes.kind[0] or "stable"}  # fmt: skip


class StabilityAt:
    """The lobes at the current speed of the current run, computed off the event loop: ``get``
    answers at once (None while the first computation runs; the last result meanwhile)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._key: tuple[object, float] | None = None  # (run, rpm) computed or being computed
        self._result: LobesAt | None = None
        self._busy = False

    def get(self, run: object, case: CutCase, rpm: float) -> LobesAt | None:
        with self._lock:
            key = self._key
            same_run = key is not None and key[0] == run
            near = (
                key is not None
                and same_run
                and abs(rpm - key[1]) <= RPM_STEP_REL * max(key[1], 1.0)
            )
            if (not near) and not self._busy:
                self._key, self._busy = (run, rpm), True
                if not same_run:
                    self._result = None
                threading.Thread(target=self._compute, args=(run, case, rpm), daemon=True,
                                 name="console-lobes").start()  # fmt: skip
            return self._result if same_run or near else None

    def _compute(self, run: object, case: CutCase, rpm: float) -> None:
        try:
            out = lobes_at(case, rpm)
        except Exception as exc:  # noqa: BLE001 - one line on the page, never a dead server
            out = {"rpm": round(rpm, 1), "reason": f"lobes not computed: {exc}"[:200]}
        with self._lock:
            if self._key == (run, rpm):
                self._result = out
            self._busy = False


def margin(lobes: LobesAt | None, case: CutCase) -> Margin:
    """What the page shows beside the spectrum: predicted chatter frequency, the run's depth
    against the limiting depth at this speed (``depth_pct``: depth / limit; over 100 %: the lobes
    predict chatter), or why not."""
    if "reason" in case:
        return {"reason": case["reason"]}
    if lobes is None:
        return {"reason": "lobes being computed for this speed"}
    out: Margin = {**lobes}
    if "reason" in lobes:
        return out
    depth, limit = case["depth_mm"], lobes["depth_limit_mm"]
    out["depth_mm"] = depth
    if limit is None or not math.isfinite(depth):
        out["depth_pct"], out["stable"] = None, True
        return out
    out["depth_pct"], out["stable"] = round(100.0 * depth / limit, 1), depth < limit
    return out


def detected_peak(force_n: np.ndarray, rate_hz: float, rpm: float) -> Peak:
    """The spectrum's strongest frequency off the spindle harmonics in ``force_n`` (n, c) N, its
    share of the energy and the detector's verdict on this window (too few cutting
    revolutions: not judged, with the reason)."""
    from analysis.chatter import indicators

    if rpm <= 0:
        return {"judged": False, "reason": "no spindle speed"}
    st = indicators(force_n, rate_hz, rpm)
    f = st.frequency_hz
    return {"peak_hz": round(f, 1) if math.isfinite(f) else None, "judged": bool(st.judged),
            "chatter": bool(st.chatter), "energy_ratio": _r(st.energy_ratio, 3),
            "energy_threshold": st.energy_threshold, "reason": st.reason}  # fmt: skip


def _r(x: float, digits: int) -> float | None:
    return round(float(x), digits) if math.isfinite(x) else None
