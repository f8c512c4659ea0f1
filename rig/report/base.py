"""What every report section shares: the loaded runs of a campaign folder, a section, a report,
and Markdown tables. The writer is :mod:`rig.report.write`; the sections
(:mod:`rig.report.facemill`, :mod:`rig.report.feedrule`, :mod:`rig.report.afc`) import this module
only.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, cast

import numpy as np

from analysis.errors import AnalysisError
from analysis.runs import file as rf
from rig.campaign.results import ManifestRow
from rig.errors import RigError
from rig.report.results import SteadyMeans


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
    def steady_means(self) -> SteadyMeans:
        """Mean forces over the steady cutting part (offset removed), N; NaN if there is none
        (computed once: the runs table, the fit plot and the validation all use it)."""
        from analysis.runs import find_steady

        run = self.run
        rpm = float(self.conditions.get("spindle_rpm", 0.0))
        out: SteadyMeans = {"Fx_mean_N": math.nan, "Fy_mean_N": math.nan, "Fz_mean_N": math.nan,
                            "revs": 0}  # fmt: skip
        if run.force_n is None or not rpm:
            return out
        try:
            part = find_steady(run.force_n, run.rate_hz, rpm)
        except AnalysisError:
            return out
        seg = part.corrected(run.force_n[part.window], part.window.start, run.rate_hz)
        m = seg.mean(axis=0)
        return {"Fx_mean_N": float(m[0]), "Fy_mean_N": float(m[1]), "Fz_mean_N": float(m[2]),
                "revs": int(part.steady_revs)}


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


def md_table(rows: Sequence[Mapping[str, object]], floatfmt: str = ".4g") -> str:
    """A Markdown table of dict rows."""
    if not rows:
        return "(no rows)\n"
    cols = list(rows[0])

    def f(v: object) -> str:
        if isinstance(v, float | np.floating):
            return "" if math.isnan(v) else format(float(v), floatfmt)
        return str(v)

    out = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    out += ["| " + " | ".join(f(r.get(c, "")) for c in cols) + " |" for r in rows]
    return "\n".join(out) + "\n"


def load_runs(folder: Path) -> tuple[list[LoadedRun], list[ManifestRow]]:
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
    return runs, cast(list[ManifestRow], entries)  # the manifest's JSON as the campaign wrote it
