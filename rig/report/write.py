"""After a campaign: its configured analysis, written as a report folder.

``write_report(campaign_folder)`` reads the campaign as it was run (``campaign.toml`` and the
manifest in the folder) and every run file through :mod:`analysis.runs.file`, then writes::

    report/
        report.md            the summary people read (tables in Markdown)
        summary.json         the same figures for scripts
        runs.csv             one row per run: conditions, status, reason, steady mean forces,
                             the chatter verdict (analysis.chatter)
        <analysis>.csv/json  the analysis' own tables (coefficients, validation, rule, ...)
        *.png                force traces, fits, predicted vs measured, load and feed

The analysis follows ``[analysis] kind``: ``facemill-coefficients`` (seed 003: identification
and validation, :mod:`rig.report.facemill`), ``feed-rule`` (seed 001 4.2: base feed and the
derived rule, :mod:`rig.report.feedrule`), ``afc-compare`` (seed 001 4.3: constant vs
post-processed feeds, :mod:`rig.report.afc`) or ``stability-sweep`` (tap test -> modes -> lobes
-> depth sweeps' chatter onset, :mod:`rig.report.stability`; its per-speed ``onset`` list is also
at the top level of summary.json).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from analysis.errors import AnalysisError
from rig.campaign import load_campaign, mode_warnings
from rig.report.afc import afc_section
from rig.report.base import LoadedRun, Report, Section, load_runs, md_table
from rig.report.facemill import facemill_section
from rig.report.feedrule import feed_rule_section
from rig.report.plots import plot_traces
from rig.report.stability import stability_sweep_section


def _run_rows(
    runs: list[LoadedRun], entries: Sequence[Mapping[str, Any]], settings: Any = None
) -> list[dict[str, Any]]:
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
            row.update(_chatter_columns(lr, settings))
        rows.append(row)
    return rows


def _chatter_columns(lr: LoadedRun, settings: Any = None) -> dict[str, Any]:
    """The run's chatter verdict (:func:`analysis.chatter.detect_run` with the campaign's
    ``[chatter]`` settings): whether, at what frequency, in which blocks, and the two indicators
    of the whole run."""
    from analysis.chatter import detect_run

    try:
        rc = detect_run(lr.run, settings)
    except AnalysisError as exc:  # no forces in N, no spindle speed: nothing to judge
        return {"chatter": "", "chatter_reason": str(exc)}
    return {
        "chatter": rc.chatter,
        "chatter_hz": rc.frequency_hz if rc.chatter else math.nan,
        "chatter_blocks": " ".join(map(str, rc.chattering_blocks())),
        "chatter_energy_ratio": rc.whole.energy_ratio,
        "chatter_opr_ratio": rc.whole.opr_ratio,
    }


def write_report(campaign_folder: str | Path) -> Report:
    """Analyse a campaign folder's runs and write ``report/`` (see the module docstring)."""
    import matplotlib

    matplotlib.use("Agg")
    folder = Path(campaign_folder)
    campaign = load_campaign(folder / "campaign.toml")
    out = folder / "report"
    out.mkdir(parents=True, exist_ok=True)
    runs, entries = load_runs(folder)
    rows = _run_rows(runs, entries, campaign.spec.chatter.settings())
    pd.DataFrame(rows).to_csv(out / "runs.csv", index=False)
    plot_traces(runs, out / "force_traces.png", campaign.name)
    kind = campaign.spec.analysis.kind
    sections: list[Section] = []
    if kind == "facemill-coefficients":
        sections.append(facemill_section(campaign, runs, out))
    elif kind == "feed-rule":
        sections.append(feed_rule_section(campaign, runs, out))
    elif kind == "afc-compare":
        sections.append(afc_section(campaign, runs, out))
    elif kind == "stability-sweep":
        sections.append(stability_sweep_section(campaign, runs, out, folder))
    counts: dict[str, int] = {}
    for e in entries:
        counts[e.get("status", "?")] = counts.get(e.get("status", "?"), 0) + 1
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
    for s in sections:
        if "onset" in s.summary:  # the stability sweep's contract: `onset` at the top level
            summary["onset"] = s.summary["onset"]
    if campaign.spec.adaptive is not None:  # issue 29: one entry per run under the loop
        from rig.report.adaptive import adaptive_entries

        summary["adaptive"], adaptive_md = adaptive_entries(campaign, runs)
        sections.append(Section("adaptive", adaptive_md))
    md = [f"# Campaign {campaign.name}\n", f"{campaign.spec.campaign.description}\n",
          f"Rig: {campaign.spec.campaign.rig}; machine {campaign.machine.name}; tool "
          f"{campaign.spec.campaign.tool}; material {campaign.spec.campaign.material}; "
          f"{len(entries)} runs ({', '.join(f'{v} {k}' for k, v in counts.items())}).\n",
          "![force traces](force_traces.png)\n"]  # fmt: skip
    md += [f"Warning: {w}\n" for w in warnings]
    chatter = [r for r in rows if r.get("chatter") is True]
    summary["chatter_runs"] = [r["name"] for r in chatter]
    md += [f"Chatter in run {r['name']} at {r['chatter_hz']:.0f} Hz (blocks "
           f"{r['chatter_blocks'] or 'whole run'}).\n" for r in chatter]  # fmt: skip
    for s in sections:
        md += [f"## {s.title}\n", s.markdown]
    cols = ["run", "name", "status", "fz_mm", "depth_mm", "Fx_mean_N", "Fy_mean_N", "Fz_mean_N",
            "chatter"]  # fmt: skip
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
