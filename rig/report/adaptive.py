"""The campaign report's ``adaptive`` list (issue 29): one entry per run under the loop, beside
the same program run without it (the baseline) and the same cut with ``plan feed``'s offline
feeds (a ``feed_mode = "post-processed"`` run of the campaign)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from rig.adaptive.session import target_of, under_loop
from rig.report.adaptive_figures import adaptive_events, chatter_decay, cycle_time_s, within_band

if TYPE_CHECKING:
    from rig.campaign.config import Campaign


def _same_cut(a: Any, b: Any) -> bool:
    ca, cb = a.conditions, b.conditions
    return all(ca.get(k) == cb.get(k) for k in ("spindle_rpm", "depth_mm", "width_mm"))


def _chatter_cleared(lr: Any, threshold: float) -> dict[str, Any]:
    """Revolutions at the speed the loop moved the spindle to, from the move (its bytes' write
    time) to where the chatter is gone: ``physics`` from the force (:func:`chatter_decay`: the
    first revolution after which the part off the spindle harmonics stays below the detector's
    energy threshold), ``live`` to the controller's ``chatter cleared`` note (its live watch
    needs a whole window at the new speed to say so). None: no move, or never cleared."""
    import re

    move = cleared = None
    pct = 100.0
    for t, _, msg in adaptive_events(lr.run):
        m = re.search(r"pocket \d+ rpm \((\d+) %\); bytes [0-9A-Fx ]+ at ([0-9.]+) s", msg)
        if m and move is None:
            pct, move = float(m.group(1)), float(m.group(2))
        if "chatter cleared" in msg and cleared is None:
            cleared = t
    out: dict[str, Any] = {"physics": None, "live": None}
    if move is None:
        return out
    rpm = abs(float(lr.conditions["spindle_rpm"])) * pct / 100.0
    out["physics"] = chatter_decay(lr.run, move, rpm, threshold)["cleared_revs"]
    if cleared is not None:
        out["live"] = int(round((cleared - move) * rpm / 60.0))
    return out


def _feed_forward(lr: Any) -> bool | None:
    """Whether the loop anticipated the load (its start note says ``feed-forward: ...`` or
    ``feedback only: ...``); None when the run file does not say (an older run)."""
    for _, _, msg in adaptive_events(lr.run):
        if "; feed-forward: " in msg:
            return True
        if "; feedback only" in msg:
            return False
    return None


def adaptive_entries(campaign: Campaign, runs: list[Any]) -> tuple[list[dict[str, Any]], str]:
    """(the JSON list, its Markdown) for the finished runs ``runs`` (LoadedRun)."""
    a = campaign.spec.adaptive
    if a is None:
        return [], ""

    def test_of(lr: Any) -> Any:
        return next(t for t in campaign.tests if t.name == lr.name)

    loop = [lr for lr in runs if under_loop(campaign, test_of(lr))]
    rest = [lr for lr in runs if lr not in loop]
    out = []
    for lr in loop:
        base = next((b for b in rest if _same_cut(b, lr) and test_of(b).feed_mode ==
                     test_of(lr).feed_mode and test_of(b).feed_mm_min == test_of(lr).feed_mm_min),
                    None)  # fmt: skip
        plan = next((b for b in rest if test_of(b).feed_mode == "post-processed"
                     and _same_cut(b, lr)), None)  # fmt: skip
        holds = a.mode in ("feed", "both")  # a spindle-only loop holds no force target
        target, target_from = target_of(campaign, test_of(lr))
        w: Mapping[str, object] = {"within": None}  # BandFigures when judged
        wb: Mapping[str, object] | None = None
        if holds and target is not None:
            w = within_band(lr, target)
            wb = within_band(base, target) if base is not None else None
        e: dict[str, Any] = {
            "run": lr.name,
            "mode": a.mode,
            # the loop set the feed ahead from the pass's predicted load (else feedback only)
            "feed_forward": _feed_forward(lr),
            "target_force_n": target,
            "target_from": target_from,
            "within_10pct": w["within"],
            # the same share over the reachable cutting time only: the revolutions the
            # controller did not report saturated (at an override limit, target out of reach)
            "within_10pct_reachable": w.get("within_reachable"),
            "saturated_s": w.get("saturated_s"),
            "saturated_revolutions": w.get("saturated_revolutions"),
            "baseline_within_10pct": None if wb is None else wb["within"],
            "cycle_time_s": cycle_time_s(lr.run),
            "baseline_cycle_time_s": None if base is None else cycle_time_s(base.run),
            "plan_feed_cycle_time_s": None if plan is None else cycle_time_s(plan.run),
            "baseline_run": None if base is None else base.name,
            "plan_feed_run": None if plan is None else plan.name,
        }
        if base is None:
            e["baseline_reason"] = "no run of the same cut and feed without the loop"
        if plan is None:
            e["plan_feed_reason"] = ('no feed_mode = "post-processed" run of the same cut in '
                                     "the campaign")  # fmt: skip
        if not holds:
            e["within_reason"] = "the spindle mode holds no force target"
        if a.mode != "feed":
            # the force's own (physics), and the live watch's confirmation apart
            cl = _chatter_cleared(lr, campaign.spec.chatter.settings().energy_ratio)
            e["chatter_cleared_revs"] = cl["physics"]
            e["chatter_cleared_live_revs"] = cl["live"]
        out.append(e)

    def num(v: Any, f: str) -> str:
        return "n/a" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, f)

    md = ["Per-revolution mean feed-plane force within +-10 % of the target, share of the "
          "cutting revolutions (as the AFC report counts them), and the same share over the "
          "reachable revolutions only (those the controller did not report saturated: cut at "
          "an override limit with the target out of reach; their time is `saturated s`); cycle "
          "time from the program's start to its last block's end.\n",
          "| run | mode | feed-forward | target N | within | within (reachable) | saturated s | "
          "baseline within | cycle s | baseline cycle s | plan feed cycle s |",
          "|---|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for e in out:
        ff = {True: "yes", False: "no", None: "n/a"}[e["feed_forward"]]
        md.append(f"| {e['run']} | {e['mode']} | {ff} | {num(e['target_force_n'], '.4g')} | "
                  f"{num(e['within_10pct'], '.3f')} | {num(e['within_10pct_reachable'], '.3f')} | "
                  f"{num(e['saturated_s'], '.2f')} | {num(e['baseline_within_10pct'], '.3f')} | "
                  f"{num(e['cycle_time_s'], '.2f')} | {num(e['baseline_cycle_time_s'], '.2f')} | "
                  f"{num(e['plan_feed_cycle_time_s'], '.2f')} |")  # fmt: skip
    return out, "\n".join(md) + "\n"
