"""The feed post-processor and the Z-map simulation as `cutlab plan feed|simulate` print them:
the status notes (stderr) and the tables of before and after (stdout)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol

from analysis.output import table_lines

__all__ = ["feed_lines", "feed_notes", "simulate_lines", "simulate_notes"]


class Contact(Protocol):
    """A holder contact of the Z-map simulation (planning.stock's HolderContact)."""

    def message(self, file: str = ...) -> str: ...


def feed_notes(
    s_json: Mapping[str, object], contacts: Sequence[Contact], program: Path, output: Path
) -> list[str]:
    """What `plan feed` wrote, the holder contacts, its notes and each tool's rule lookup."""
    s: Any = s_json  # the job's JSON result, read by key
    out = [
        f"wrote {output} ({s['dialect']}) and report "
        f"{Path(s['report']['csv']).parent}/{output.stem}-*"
    ]
    out += ["warning: " + c.message(str(program)) for c in contacts]
    out += ["note: " + n for n in s["notes"]]
    for r in s.get("rule_lookup", ()):  # each tool's rule from the rule base (no --rules)
        found = f"rule {r['rule']} (group {r['group']})" if r["rule"] else "no rule"
        out.append(
            f"T{r['tool_number']} {r['tool']}: {found}"
            + (f": {r['reason']}" if r.get("reason") else "")
        )
    return out


def feed_lines(s_json: Mapping[str, object]) -> list[str]:
    """The machining time and load before and after, each tool's share, the time saved."""
    s: Any = s_json  # the job's JSON result, read by key
    rows = (
        ("machining time (s)", "time_%s_s"),
        ("with acceleration (s)", "accel_time_%s_s"),
        ("max load x feed", "load_rate_max_%s"),
    )
    out = table_lines(
        [{"": t, "before": s[k % "before"], "after": s[k % "after"]} for t, k in rows]
    )
    if len(s["tools"]) > 1:  # each tool's share (a tool without a rule keeps its feeds)
        out += table_lines(
            [{k: ("(kept)" if v is None else v) for k, v in t.items()} for t in s["tools"]]
        )
    out.append(
        f"time saved {s['time_saved_pct']:.1f} %, {s['split_blocks']} blocks split, "
        f"removed {s['removed_mm3']:.1f} mm^3"
    )
    return out


def simulate_notes(
    out_json: Mapping[str, object], contacts: Sequence[Sequence[Contact]]
) -> list[str]:
    """The holder contacts of each operation (``contacts``: each operation's)."""
    out: Any = out_json  # the job's JSON result, read by key
    return [
        "warning: " + c.message(r["file"]) for r, cs in zip(out["operations"], contacts) for c in cs
    ]


def simulate_lines(out_json: Mapping[str, object]) -> list[str]:
    """Each operation's segments, removal, time and holder contacts; each tool's share."""
    out: Any = out_json  # the job's JSON result, read by key
    cols = ("operation", "tool", "segments", "removed_mm3", "time_s")
    lines = table_lines(
        [
            {k: r[k] for k in cols} | {"holder_contacts": len(r["holder_contacts"])}
            for r in out["operations"]
        ]
    )
    if any(len(r["tools"]) > 1 for r in out["operations"]):  # each tool's share
        lines += table_lines(
            [{"operation": r["operation"]} | t for r in out["operations"] for t in r["tools"]]
        )
    return lines
