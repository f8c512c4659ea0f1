"""What `plan feed`'s force and limit options ask of the limits, checked together: ``--material``
(the force coefficients), ``--limit`` (cap the feeds), ``--force-limit``, ``--lobes``, for a
one-tool program; with T1=A,T2=B and no ``--rules``, ``--material`` only finds each tool's rule
in the rule base."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from analysis.config import load_machine
from planning.errors import PlanningError
from planning.feed import end_mill
from planning.limits.job import CheckStep, FeedCap, coefficients, feed_limiter
from planning.limits.model import limits_for

__all__ = ["FeedLimits", "feed_limits"]


@dataclass(frozen=True)
class FeedLimits:
    """The feed cap (None unless ``--limit``), the step that checks the written program (None
    without ``--material``), and whether ``--material`` only looks the rules up."""

    cap: FeedCap | None = None
    step: CheckStep | None = None
    lookup_only: bool = False


def feed_limits(
    rules: str | None, tool_name: str | None, material: str | None, machine: str,
    lobes: Path | None, force_limit_n: float | None, fix: bool, spindle_rpm: float | None,
) -> FeedLimits:  # fmt: skip
    """The limits of a `plan feed` call; a combination the limits cannot serve is refused."""
    # no --rules with T1=A,T2=B: --material only finds each tool's rule in the rule base
    lookup_only = rules is None and bool(tool_name) and "=" in (tool_name or "")
    if material and tool_name and "=" in tool_name and not lookup_only:
        raise PlanningError(
            f"--material with --tool {tool_name}: the force and limit options work on a one-tool "
            "program; check the output per tool with `cutlab plan check OUT --tool T1=A,T2=B`"
        )
    if material and not lookup_only:  # the limits need the force coefficients
        tool = end_mill(tool_name)
        limits = limits_for(tool, load_machine(machine), tool_name=tool_name or "", lobes=lobes,
                            force_limit_n=force_limit_n)  # fmt: skip
        cap, step = feed_limiter(tool, coefficients(material), limits, fix=fix,
                                 spindle_rpm=spindle_rpm)  # fmt: skip
        return FeedLimits(cap, step)
    if fix:
        raise PlanningError("--limit needs --material (its [endmill] coefficients)")
    return FeedLimits(lookup_only=lookup_only)
