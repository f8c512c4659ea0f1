"""What a run file or an export holds, as the text of `cutlab data info`."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from analysis.output import table_lines

__all__ = ["export_info_lines", "run_info_lines"]


def export_info_lines(s_json: Mapping[str, object]) -> list[str]:
    """An export's summary (:func:`analysis.runs.table.table_summary`) as lines."""
    s: Any = s_json  # the job's JSON result, read by key
    out: list[str] = []
    keys = ("format", "rate_hz", "samples", "duration_s", "decimal", "separator")
    rows = [{"quantity": k, "value": s[k]} for k in keys]
    rows.insert(
        1,
        {
            "quantity": "columns",
            "value": " ".join(f"{c} [{u}]" if u else c for c, u in zip(s["columns"], s["units"])),
        },
    )
    rows += [{"quantity": f"header: {k}", "value": v} for k, v in s["header"].items()]
    out += table_lines(rows)
    return out


def run_info_lines(s_json: Mapping[str, object]) -> list[str]:
    """A run file's summary (:func:`analysis.runs.run_summary`) as lines: INCOMPLETE first when
    the writer never closed it, then its quantities and its gaps."""
    s: Any = s_json  # the job's JSON result, read by key
    out: list[str] = []
    if not s["complete"]:
        out.append(
            f"INCOMPLETE: the writer never closed {s['file']} (killed or still running); it holds "
            f"{s['samples_stored']} samples per channel = {s['duration_s']:.3f} s up to its last "
            "flush"
        )
    keys = (
        "status reason sample_format rate_hz samples_stored samples_acquired samples_lost "
        "duration_s nc_blocks calibration_id software_version"
    ).split()
    rows = [{"quantity": k, "value": s[k]} for k in keys]
    rows.insert(1, {"quantity": "channels", "value": " ".join(s["channels"])})
    rows.append(
        {"quantity": "events", "value": ", ".join(f"{k} {v}" for k, v in s["events"].items())}
    )
    if s["conditions"]:
        rows.append({"quantity": "conditions", "value": s["conditions"]})
    out += table_lines(rows)
    if s["gaps"]:
        out.append("")
        out += table_lines(s["gaps"])
    return out
