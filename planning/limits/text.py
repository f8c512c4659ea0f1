"""The limits' verdict as the plan commands print it: the violations, the verdict line with each
limit that could not be checked, the worst margins of `plan check`, the limits' fixes of `plan
rough --limit`, and the note on a derived stock."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, cast

from analysis.output import table_lines
from analysis.validation import JsonValue
from planning.rough.job import RoughResult
from planning.rough.text import rough_lines

__all__ = ["RoughAnswer", "check_lines", "rough_answer", "rough_limit_lines", "rough_text",
           "stock_note", "verdict_lines", "violation_lines"]  # fmt: skip

#: violations listed in the text (--json lists all)
VIOLATIONS_SHOWN = 20


def violation_lines(
    violations_json: Sequence[Mapping[str, object]], limit: int = VIOLATIONS_SHOWN
) -> list[str]:
    """The first ``limit`` violations as a table under a count line (none: no lines)."""
    violations: Any = violations_json  # the job's JSON result, read by key
    if not violations:
        return []
    out = [f"{len(violations)} violations (block, limit, value, allowed, margin %):"]
    out += table_lines(violations[:limit])
    if len(violations) > limit:
        out.append(f"... and {len(violations) - limit} more (--json lists all)")
    return out


def verdict_lines(out_json: Mapping[str, object]) -> list[str]:
    """The verdict line, then each limit that could not be checked and why."""
    out: Any = out_json  # the job's JSON result, read by key
    n = len(out["violations"])
    line = {
        "within": "verdict: within: every block within every limit",
        "violations": f"verdict: violations: {n} (block, limit) over a limit",
        "unchecked": "verdict: unchecked: no block over a checked limit, but these limits "
        "were not checked:",
    }[out["verdict"]]
    lines = [line]
    for u in out["unchecked"]:
        tool = f"{u['tool']} " if u.get("tool") else ""
        lines.append(f"  not checked: {tool}{u['limit']}: {u['reason']}")
    return lines


def stock_note(stock_json: Mapping[str, object]) -> str | None:
    """The stock a job derived from the program's feed moves (None: it was given)."""
    stock: Any = stock_json  # the job's JSON result, read by key
    if stock.get("source") == "derived":
        return f"stock: {stock['spec']} (derived: {stock['how']})"
    return None


def check_lines(out_json: Mapping[str, object]) -> list[str]:
    """`plan check`'s text (:func:`planning.limits.check_job`'s result): each tool's share, the
    violations, the worst margin of each quantity and the verdict."""
    out: Any = out_json  # the job's JSON result, read by key
    lines: list[str] = []
    if len(out["tools"]) > 1:
        cols = (
            "tool_number",
            "tool",
            "removed_mm3",
            "time_s",
            "cutting_blocks",
            "violations",
            "verdict",
        )
        lines += table_lines([{k: r[k] for k in cols} for r in out["tools"]])
    lines += violation_lines(out["violations"])
    for k, w in out["worst"].items():
        tool = f"{w['tool']} " if w.get("tool") else ""
        lines.append(
            f"worst {k}: {w['value']:.4g} of {w['allowed']:.4g} at {tool}block {w['block']} "
            f"(margin {w['margin_pct']} %)"
        )
    return lines + verdict_lines(out)


def rough_limit_lines(res_json: Mapping[str, object]) -> list[str]:
    """What `plan rough --limit` changed (levels split, feeds lowered) and what is left over."""
    res: Any = res_json  # the job's JSON result, read by key
    lim = res["limits"]
    if lim is None or not lim.get("before"):
        return []
    b, af = lim["before"], lim["after"]
    lines = [
        f"limits: {b['violations']} violations before, {af['violations']} after; levels "
        f"{b['levels']} -> {af['levels']}, cutting path {b['cutting_path_mm']} -> "
        f"{af['cutting_path_mm']} mm, time {b['time_s']} -> {af['time_s']} s "
        f"(+{lim['time_lost_s']} s)"
    ]
    for sp in lim["levels_split"]:
        lines.append(
            f"  split level z = {sp['z_mm']} mm ({sp['height_mm']} mm deep) in {sp['parts']}"
        )
    if ns := lim.get("not_split"):
        z = [n["z_mm"] for n in ns]
        a = [n["allowed_mm"] for n in ns]
        lines.append(
            f"  not split for stability: {len(ns)} levels (z {min(z)}-{max(z)} mm): stable depth "
            f"{min(a)}-{max(a)} mm needs sub-levels under the part's dh_mm {ns[0]['dh_mm']}, and "
            "more passes that chatter do not cure it: another spindle speed, a stiffer tool or a "
            "smaller dh_mm"
        )
    if lim["feeds_lowered"]:
        lines.append(f"  lowered the feed of {len(lim['feeds_lowered'])} blocks")
    return lines + violation_lines(res["violations"])


class RoughAnswer(RoughResult):
    """``cutlab plan rough``'s result: the job's, with the written program's limits verdict
    and the limits that were not checked."""

    verdict: str
    unchecked: JsonValue


def rough_answer(res: RoughResult) -> RoughAnswer:
    """``res`` with the limits' verdict of the written program (``unchecked`` when the limits
    were not run) and what they could not check."""
    lim = res["limits"] or {}
    answer = cast(RoughAnswer, res)
    answer["verdict"] = str(lim.get("verdict", "unchecked"))
    answer["unchecked"] = lim.get("unchecked", [{"limit": "all", "reason": "limits not run"}])
    return answer


def rough_text(res: RoughAnswer) -> list[str]:
    """``cutlab plan rough``'s text: the chosen method's levels and every method's totals, what
    the limits changed, the verdict, then the pictures written."""
    pictures = [f"{k}: {v}" for k, v in res["png"].items()]
    return [*rough_lines(res, res["method"]), *rough_limit_lines(res), *verdict_lines(res),
            *pictures]  # fmt: skip
