"""After a campaign: its configured analysis, written as a report folder.

``write_report(campaign_folder)`` reads the campaign as it was run (``campaign.toml`` and the
manifest in the folder) and every run file through :mod:`analysis.runs.file`, then writes::

    report/
        report.md            the summary people read (tables in Markdown)
        summary.json         the same figures for scripts
        runs.csv             one row per run: conditions, status, reason, steady mean forces
        <analysis>.csv/json  the analysis' own tables (coefficients, validation, rule, ...)
        *.png                force traces, fits, predicted vs measured, load and feed

The analysis follows ``[analysis] kind``: ``facemill-coefficients`` (seed 003: identification
and validation, :mod:`rig.report.facemill`), ``feed-rule`` (seed 001 4.2: base feed and the
derived rule, :mod:`rig.report.feedrule`) or ``afc-compare`` (seed 001 4.3: constant vs
post-processed feeds, :mod:`rig.report.afc`).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from analysis.errors import AnalysisError
from analysis.runs import file as rf
from rig.errors import RigError


@dataclass(frozen=True)
class LoadedRun:
    """A finished run of the campaign: its manifest entry and its loaded file."""

    index: int
    name: str
    group: str
    path: Path
    run: rf.Run

    @property
    def conditions(self) -> dict[str, Any]:
        return self.run.conditions

    @cached_property
    def steady_means(self) -> dict[str, float]:
        """Mean forces over the steady cutting part (offset removed), N; NaN if there is none
        (computed once: the runs table, the fit plot and the validation all use it)."""
        from analysis.runs.steady import find_steady

        run = self.run
        rpm = float(self.conditions.get("spindle_rpm", 0.0))
        out = {"Fx_mean_N": math.nan, "Fy_mean_N": math.nan, "Fz_mean_N": math.nan, "revs": 0}
        if run.force_n is None or not rpm:
            return out
        try:
            part = find_steady(run.force_n, run.rate_hz, rpm)
        except AnalysisError:
            return out
        seg = part.corrected(run.force_n[part.window], part.window.start, run.rate_hz)
        m = seg.mean(axis=0)
        out.update(Fx_mean_N=float(m[0]), Fy_mean_N=float(m[1]), Fz_mean_N=float(m[2]),
                   revs=int(part.steady_revs))  # fmt: skip
        return out


@dataclass(frozen=True)
class Section:
    """One part of the report: a title, Markdown text, figures for the summary, files written."""

    title: str
    markdown: str
    summary: dict[str, Any] = field(default_factory=dict)
    files: tuple[str, ...] = ()


@dataclass(frozen=True)
class Report:
    folder: Path
    summary: dict[str, Any]
    markdown: str


def md_table(rows: list[dict[str, Any]], floatfmt: str = ".4g") -> str:
    """A Markdown table of dict rows."""
    if not rows:
        return "(no rows)\n"
    cols = list(rows[0])

    def f(v: Any) -> str:
        if isinstance(v, float | np.floating):
            return "" if math.isnan(v) else format(float(v), floatfmt)
        return str(v)

    out = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    out += ["| " + " | ".join(f(r.get(c, "")) for c in cols) + " |" for r in rows]
    return "\n".join(out) + "\n"


def load_runs(folder: Path) -> tuple[list[LoadedRun], list[dict[str, Any]]]:
    """Successful runs (loaded) and every manifest entry, in test order."""
    mpath = folder / "campaign.json"
    if not mpath.exists():
        raise RigError(f"{folder}: no campaign.json: not a campaign folder (run the campaign)")
    manifest = json.loads(mpath.read_text())
    entries = sorted(
        ({"name": k, **v} for k, v in manifest.get("runs", {}).items()), key=lambda e: e["index"]
    )
    runs = []
    for e in entries:
        if e.get("status") != rf.STATUS_SUCCESS:
            continue
        path = folder / e["file"]
        run = rf.load_run(path)
        runs.append(LoadedRun(e["index"], e["name"], e.get("group", ""), path, run))
    return runs, entries


def _run_rows(runs: list[LoadedRun], entries: list[dict[str, Any]]) -> list[dict[str, Any]]:
    by_name = {r.name: r for r in runs}
    rows = []
    for e in entries:
        c = e.get("conditions", {})
        row: dict[str, Any] = {
            "run": e["index"],
            "name": e["name"],
            "group": e.get("group", ""),
            "status": e.get("status", ""),
            "reason": e.get("reason", ""),
            "fz_mm": c.get("fz_mm", math.nan),
            "feed_mm_min": c.get("feed_mm_min", math.nan),
            "depth_mm": c.get("depth_mm", math.nan),
            "spindle_rpm": c.get("spindle_rpm", math.nan),
        }
        lr = by_name.get(e["name"])
        if lr is not None:
            row["duration_s"] = lr.run.duration_s
            row["samples_lost"] = lr.run.samples_lost
            row.update(lr.steady_means)
            if lr.run.force_n is not None:
                row["peak_N"] = float(np.max(np.linalg.norm(lr.run.force_n, axis=1)))
        rows.append(row)
    return rows


def write_report(campaign_folder: str | Path) -> Report:
    """Analyse a campaign folder's runs and write ``report/`` (see the module docstring)."""
    import matplotlib

    matplotlib.use("Agg")
    from rig.campaign.config import load_campaign
    from rig.report.plots import plot_traces

    folder = Path(campaign_folder)
    campaign = load_campaign(folder / "campaign.toml")
    out = folder / "report"
    out.mkdir(parents=True, exist_ok=True)
    runs, entries = load_runs(folder)
    rows = _run_rows(runs, entries)
    pd.DataFrame(rows).to_csv(out / "runs.csv", index=False)
    plot_traces(runs, out / "force_traces.png", campaign.name)
    kind = campaign.spec.analysis.kind
    sections: list[Section] = []
    if kind == "facemill-coefficients":
        from rig.report.facemill import facemill_section

        sections.append(facemill_section(campaign, runs, out))
    elif kind == "feed-rule":
        from rig.report.feedrule import feed_rule_section

        sections.append(feed_rule_section(campaign, runs, out))
    elif kind == "afc-compare":
        from rig.report.afc import afc_section

        sections.append(afc_section(campaign, runs, out))
    counts: dict[str, int] = {}
    for e in entries:
        counts[e.get("status", "?")] = counts.get(e.get("status", "?"), 0) + 1
    from rig.campaign.runner import mode_warnings

    warnings = mode_warnings(campaign)
    summary: dict[str, Any] = {
        "campaign": campaign.name,
        "mode_warnings": warnings,
        "description": campaign.spec.campaign.description,
        "rig": campaign.spec.campaign.rig,
        "runs": len(entries),
        "status_counts": counts,
        "analysis": kind,
        **{s.title: s.summary for s in sections},
    }
    md = [f"# Campaign {campaign.name}\n", f"{campaign.spec.campaign.description}\n",
          f"Rig: {campaign.spec.campaign.rig}; machine {campaign.machine.name}; tool "
          f"{campaign.spec.campaign.tool}; material {campaign.spec.campaign.material}; "
          f"{len(entries)} runs ({', '.join(f'{v} {k}' for k, v in counts.items())}).\n",
          "![force traces](force_traces.png)\n"]  # fmt: skip
    md += [f"Warning: {w}\n" for w in warnings]
    for s in sections:
        md += [f"## {s.title}\n", s.markdown]
    cols = ["run", "name", "status", "fz_mm", "depth_mm", "Fx_mean_N", "Fy_mean_N", "Fz_mean_N"]
    md += ["## Runs\n", md_table([{k: r.get(k, "") for k in cols} for r in rows])]
    text = "\n".join(md)
    (out / "report.md").write_text(text)
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=_jsonable))
    return Report(out, summary, text)


def _jsonable(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(type(o).__name__)
