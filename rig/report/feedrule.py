"""Report section for seed 001 4.2: the base feed from a feed sweep and the derived feed rule.

The sweep's runs go to :func:`analysis.rules.basefeed.find_base_feed` (force-slope and vibration
jumps); the rule is :func:`analysis.rules.rule.derive_rule` with the campaign's ``[feed_rule]`` min
and max, the base feed found (the configured one if the sweep shows none) and the reference load of
the sweep's slot. The rule is written as a TOML file the post-processor reads.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pandas as pd

from analysis.errors import AnalysisError
from rig.report.base import LoadedRun, Section, md_table

if TYPE_CHECKING:
    from rig.campaign.config import Campaign


def feed_rule_section(campaign: Campaign, runs: list[LoadedRun], out: Path) -> Section:
    from analysis.rules import (
        derive_rule,
        find_base_feed,
        plot_rule,
        save_rule,
        sweep_runs_from_files,
    )

    groups = campaign.spec.analysis.identify_groups
    sweep_runs = [lr for lr in runs if not groups or lr.group in groups]
    try:
        sweep = sweep_runs_from_files([lr.path for lr in sweep_runs])
        res = find_base_feed(sweep.runs)
    except AnalysisError as exc:
        msg = f"no base feed: {exc}"
        return Section("feed-rule", msg + "\n", {"success": False, "message": msg})
    fr = campaign.spec.feed_rule
    if res.found and res.base_feed_mm_min is not None:  # found: the base feed is set
        base = res.base_feed_mm_min
    else:
        base = fr.base_feed_mm_min if fr else math.nan
    rows = [
        {"feed_mm_min": s.feed_mm_min, "mean_resultant_N": s.mean_resultant_n,
         "peak_resultant_N": s.peak_resultant_n, "vibration_rms_N": s.vibration_rms_n,
         "revolutions": s.revolutions}
        for s in res.runs
    ]  # fmt: skip
    pd.DataFrame(rows).to_csv(out / "sweep.csv", index=False)
    pd.DataFrame(res.table()).to_csv(out / "sweep_intervals.csv", index=False)
    summary: dict[str, Any] = {
        "success": bool(res.found),
        "message": res.message,
        "base_feed_mm_min": base,
        "reference_load_pct": sweep.reference_load_pct,
    }
    # res.message is a sentence of its own ("base feed 1000 mm/min: between ..."): no prefix
    md = [f"{res.message[:1].upper()}{res.message[1:]}.\n", md_table(rows)]
    _plot_sweep(rows, base, out / "sweep.png", campaign.name)
    md.append("![force against feed](sweep.png)\n")
    if fr is not None and sweep.reference_load_pct and math.isfinite(base):
        name = campaign.spec.analysis.rule_name
        rule = derive_rule(
            name, fr.min_feed_mm_min, base, fr.max_feed_mm_min, sweep.reference_load_pct,
            fr.exponent, fr.n_bins, description=f"derived by campaign {campaign.name}",
            source=str(out.parent / "campaign.toml"), tool=sweep.tool or "",
        )  # fmt: skip
        path = save_rule(rule, out / f"{name}.toml")
        plot_rule(rule, out / "rule.png")
        summary["rule_file"] = str(path)
        summary["rule"] = {"min": fr.min_feed_mm_min, "base": base, "max": fr.max_feed_mm_min,
                           "bins": int(fr.n_bins)}  # fmt: skip
        md += [f"Rule `{name}` written to `{path.name}` ({fr.n_bins} bins, "
               f"{fr.min_feed_mm_min:g}..{fr.max_feed_mm_min:g} mm/min around {base:g}).\n",
               "![rule](rule.png)\n"]  # fmt: skip
    (out / "feed_rule.json").write_text(json.dumps(summary, indent=2, default=float))
    return Section("feed-rule", "\n".join(md), summary, ("sweep.csv", "feed_rule.json"))


def _plot_sweep(rows: list[dict], base: float, path: Path, title: str) -> None:
    from rig.report.plots import _plt

    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 3.8))
    f = [r["feed_mm_min"] for r in rows]
    ax.plot(f, [r["mean_resultant_N"] for r in rows], "o-", label="mean |Fxy| per rev")
    ax.plot(f, [r["peak_resultant_N"] for r in rows], "s--", label="peak |Fxy| per rev")
    # the vibration (a few N) on its own axis: on the force axis (hundreds of N) it reads as 0
    ax2 = ax.twinx()
    ax2.plot(f, [r["vibration_rms_N"] for r in rows], "^:", color="tab:green",
             label="vibration rms (right axis)")  # fmt: skip
    ax2.set_ylabel("vibration rms, N", color="tab:green")
    ax2.set_ylim(bottom=0)
    if math.isfinite(base):
        ax.axvline(base, color="k", lw=0.8, label=f"base feed {base:g} mm/min")
    ax.set_xlabel("feed, mm/min")
    ax.set_ylabel("force, N")
    ax.set_ylim(bottom=0)
    ax.set_title(f"{title}: feed sweep", fontsize=9)
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, fontsize=7, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
