"""The stability-sweep analysis (``[analysis] kind = "stability-sweep"``): the tool's tap test
-> its modes -> stability lobes -> the depth sweeps' detected chatter onset beside the
predicted limit, per spindle speed.

1. Modes: each tap record the campaign made (``tap/tap_x.csv``, ``tap_y.csv``:
   :func:`rig.campaign.runner.tap_records`) through :func:`analysis.modal.modal_file`, saved as
   ``report/modes.toml`` (``cutlab analyze modal --save``'s file).
2. Lobes: :func:`analysis.stability.stability_lobes` with the MEASURED modes, the material's
   cutting coefficients (Ktc, Krc) and the cut of the sweep (teeth, radial immersion, milling
   mode), over the sweep's speeds and a grid around them; on the simulated rig also with the
   twin's true modes, for comparison only.
3. Per speed: every cut's verdict (:func:`analysis.chatter.detect_run`, with the campaign's
   ``[chatter]`` thresholds); the observed onset is the
   shallowest depth detected as chatter, bracketed below by the deepest stable cut under it; it
   is within tolerance when it lies within ``onset_tolerance_pct`` of the predicted limit.

Writes ``onset.csv``, ``lobes.csv``, ``modes.toml`` and ``lobes.png`` (the lobes with every cut
marked stable or chatter).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np
import pandas as pd

from analysis.errors import AnalysisError
from rig.campaign.runner import twin_tool_modes
from rig.report.base import LoadedRun, Section, md_table
from rig.report.results import OnsetRow

if TYPE_CHECKING:
    from rig.campaign.config import Campaign

TITLE = "Stability sweep"
#: The lobes are computed from this fraction below the slowest tested speed to this above the
#: fastest, plus the tested speeds themselves.
RPM_MARGIN = 0.25
LOBE_POINTS = 121


def _measured_modes(campaign: Campaign, folder: Path, out: Path) -> tuple[Any, list[str]]:
    """The tap records' modes (a ModeSet), saved to ``out/modes.toml``, and warnings."""
    from analysis.modal import load_modes, modal_file

    tap = campaign.spec.tap_test
    saved = out / "modes.toml"
    saved.unlink(missing_ok=True)  # save_modes merges into an existing file
    notes: list[str] = []
    for axis in ("x", "y"):
        rec = folder / "tap" / f"tap_{axis}.csv"
        if not rec.exists():
            raise AnalysisError(f"{rec}: no tap record in direction {axis}: run the campaign")
        res = modal_file(rec, response=tap.response if tap else None, save=saved)
        # modal_file's JSON: warnings are lines, skipped channels {channel, reason, ...}
        warnings = cast(list[str], res["warnings"])
        skipped = cast(list[dict[str, str]], res["skipped"])
        notes += [f"tap {axis}: {w}" for w in warnings]
        notes += [f"tap {axis}: {s['channel']}: {s['reason']}" for s in skipped]
    return load_modes(saved), notes


def _case(
    campaign: Campaign,
    runs: list[LoadedRun],
    modes: Sequence[tuple[str, float, float, float]],
    rpm: np.ndarray,
) -> Any:
    """The stability case of the sweep's cut with ``modes`` (direction, f Hz, zeta, k N/m)."""
    from analysis.stability import StabilityCase

    coef = campaign.material.endmill
    assert coef is not None  # stability_sweep_section refuses a material without them
    tool = campaign.tool
    widths = {round(float(r.conditions.get("width_mm", tool.diameter_mm)), 6) for r in runs}
    if len(widths) != 1:
        raise AnalysisError(f"stability sweep: one radial width for all cuts, got {sorted(widths)}")
    immersion = min(widths.pop() / tool.diameter_mm, 1.0)
    milling = "up" if runs[0].conditions.get("mode") == "up" else "down"
    d, f, z, k = zip(*modes)
    return StabilityCase(
        teeth=campaign.teeth, milling=milling, radial_immersion=immersion,
        kt_n_m2=coef.Ktc_n_mm2 * 1e6, kn_n_m2=coef.Krc_n_mm2 * 1e6, f_hz=np.array(f),
        zeta=np.array(z), k_n_m=np.array(k), direction=tuple(d), rpm=rpm, name=campaign.name,
    )  # fmt: skip


def _limit_at(lobes: Any, rpm: float) -> float:
    i = int(np.argmin(np.abs(lobes.spindle_rpm - rpm)))
    return float(lobes.depth_limit_mm[i])


def onset_rows(
    verdicts: list[tuple[float, float, bool]], predicted: dict[float, float], tol_pct: float
) -> list[OnsetRow]:
    """Per speed, from (spindle rpm, depth mm, chatter) of each cut and the predicted limit per
    speed: the observed onset (shallowest chattering depth, or None with a reason), its bracket
    (deepest stable depth below it, onset), the error against the prediction in %, and whether
    it is within ``tol_pct``; stable cuts deeper than the onset are listed."""
    rows: list[OnsetRow] = []
    for rpm in sorted({v[0] for v in verdicts}):
        cuts = sorted((d, c) for n, d, c in verdicts if n == rpm)
        pred = predicted[rpm]
        row: OnsetRow = {"spindle_rpm": rpm}
        if math.isfinite(pred):
            row["predicted_limit_mm"] = pred
        else:
            row |= {"predicted_limit_mm": None,
                    "predicted_limit_mm_reason": "stable at every depth searched"}  # fmt: skip
        chat = [d for d, c in cuts if c]
        row["depths_mm"] = [d for d, _ in cuts]
        row["chatter"] = [c for _, c in cuts]
        if not chat:
            why = f"no cut chattered (deepest {cuts[-1][0]:g} mm)"
            row |= {"observed_onset_mm": None, "observed_onset_mm_reason": why,
                    "bracket_mm": None, "error_pct": None, "within_tolerance": False}  # fmt: skip
            rows.append(row)
            continue
        onset = chat[0]
        below = [d for d, c in cuts if not c and d < onset]
        row["observed_onset_mm"] = onset
        row["bracket_mm"] = [below[-1] if below else None, onset]
        row["stable_above_onset_mm"] = [d for d, c in cuts if not c and d > onset]
        if math.isfinite(pred):
            err = 100.0 * (onset - pred) / pred
            row["error_pct"] = err
            row["within_tolerance"] = abs(err) <= tol_pct
        else:
            row |= {"error_pct": None, "within_tolerance": False}
        rows.append(row)
    return rows


def _plot(path: Path, lobes: Any, true_lobes: Any, verdicts: list, rows: list, title: str) -> None:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4.5))
    top = max([d for _, d, _ in verdicts] + [0.0]) * 1.6
    ax.plot(lobes.spindle_rpm, np.minimum(lobes.depth_limit_mm, 1e3), "k-", lw=1.2,
            label=f"limit, tapped modes ({lobes.method.upper()})")  # fmt: skip
    if true_lobes is not None:
        ax.plot(true_lobes.spindle_rpm, np.minimum(true_lobes.depth_limit_mm, 1e3), "b--",
                lw=0.8, label="limit, the twin's true modes")  # fmt: skip
    # stable and chattering cuts of one speed side by side (they overlapped at one x)
    dx = 0.006 * float(np.ptp(lobes.spindle_rpm) or 1.0)
    for chatter, style, name in ((False, "go", "stable cut"), (True, "rx", "chatter detected")):
        pts = [(n + (dx if chatter else -dx), d) for n, d, c in verdicts if c == chatter]
        if pts:
            ax.plot(*zip(*pts), style, ms=6, mfc="none" if not chatter else None, label=name)
    onset = [(r["spindle_rpm"], r["observed_onset_mm"]) for r in rows
             if r.get("observed_onset_mm") is not None]  # fmt: skip
    if onset:
        ax.plot(*zip(*onset), "r_", ms=18, mew=2, label="observed onset (lowest chatter)")
    ax.set_xlabel("spindle speed (rpm)")
    ax.set_ylabel("axial depth (mm)")
    ax.set_ylim(0, top or None)
    ax.set_title(title)
    ax.legend(loc="upper left", fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def stability_sweep_section(
    campaign: Campaign, runs: list[LoadedRun], out: Path, folder: Path
) -> Section:
    """The section (module docstring); ``summary["onset"]`` is the per-speed list."""
    from analysis.stability import stability_lobes

    if not runs:
        raise AnalysisError(f"{folder}: stability sweep: no successful cut to judge")
    coef = campaign.material.endmill
    if coef is None:  # a real rig's campaign is not checked for them (the twin's is)
        raise AnalysisError(
            f"{folder}: stability sweep: material {campaign.spec.campaign.material!r} has no "
            "[endmill] coefficients (Ktc, Krc, N/mm^2): no lobes"
        )
    modeset, notes = _measured_modes(campaign, folder, out)
    measured = [(d, m.frequency_hz, m.damping_ratio, m.stiffness_n_m)
                for d, ms in modeset.directions.items() if d in ("x", "y") for m in ms
                if m.stiffness_n_m is not None]  # fmt: skip
    if not measured:
        raise AnalysisError(f"{folder}/tap: no mode with a stiffness in x or y: no lobes")
    tested = sorted({float(r.conditions["spindle_rpm"]) for r in runs})
    grid = np.linspace(tested[0] * (1 - RPM_MARGIN), tested[-1] * (1 + RPM_MARGIN), LOBE_POINTS)
    rpm = np.union1d(grid, tested)
    method = campaign.spec.analysis.stability_method
    lobes = stability_lobes(_case(campaign, runs, measured, rpm), method)
    true_lobes = None
    true_modes = twin_tool_modes(campaign)  # the twin's truth, not the catalogue's measurement
    if campaign.spec.campaign.rig == "sim" and true_modes:
        truth = [(m.axis, m.f_hz, m.zeta, m.k_N_m) for m in true_modes]
        true_lobes = stability_lobes(_case(campaign, runs, truth, rpm), method)
    verdicts, cut_rows = _judged_cuts(campaign, runs)
    predicted = {n: _limit_at(lobes, n) for n in tested}
    tol = campaign.spec.analysis.onset_tolerance_pct
    rows = onset_rows(verdicts, predicted, tol)
    for row in rows:
        if true_lobes is not None:
            row["true_limit_mm"] = _limit_at(true_lobes, row["spindle_rpm"])
        i = int(np.argmin(np.abs(lobes.spindle_rpm - row["spindle_rpm"])))
        row["predicted_chatter_hz"] = float(lobes.chatter_hz[i])
    pd.DataFrame(rows).to_csv(out / "onset.csv", index=False)
    pd.DataFrame({"spindle_rpm": lobes.spindle_rpm, "depth_limit_mm": lobes.depth_limit_mm,
                  "chatter_hz": lobes.chatter_hz, "kind": lobes.kind}).to_csv(
        out / "lobes.csv", index=False)  # fmt: skip
    _plot(out / "lobes.png", lobes, true_lobes, verdicts, rows,
          f"{campaign.name}: lobes from the tap test, cuts as detected")  # fmt: skip
    table = []
    for row in rows:
        b = row.get("bracket_mm")
        table.append({
            "spindle_rpm": row["spindle_rpm"],
            "predicted_mm": row["predicted_limit_mm"] or math.nan,
            "true_modes_mm": row.get("true_limit_mm", math.nan),
            "onset_mm": row["observed_onset_mm"] or math.nan,
            "bracket_mm": "" if b is None else f"{b[0] if b[0] is not None else '-'}..{b[1]:g}",
            "error_pct": row["error_pct"] if row["error_pct"] is not None else math.nan,
            f"within_{tol:g}pct": row["within_tolerance"],
        })  # fmt: skip
    mode_rows = [{"direction": d, "f_hz": f, "zeta": z, "k_N_m": k} for d, f, z, k in measured]
    md = [
        "Tap test -> modes (report/modes.toml):\n", md_table(mode_rows),
        f"\nLobes ({method.upper()}) from the tapped modes and the material's Ktc = "
        f"{coef.Ktc_n_mm2:g}, Krc = {coef.Krc_n_mm2:g}"
        " N/mm^2; onset = the shallowest cut detected as chatter, bracketed by the deepest "
        "stable cut below it.\n", md_table(table), "\n![lobes](lobes.png)\n",
        "Cuts:\n", md_table(cut_rows),
    ]  # fmt: skip
    md += [f"Note: {n}\n" for n in notes]
    summary = {
        "modes": mode_rows,
        "method": method,
        "onset_tolerance_pct": tol,
        "onset": rows,
        "all_within_tolerance": all(r["within_tolerance"] for r in rows),
        "cuts": cut_rows,
        "notes": notes,
    }
    return Section(TITLE, "\n".join(md), summary,
                   ("onset.csv", "lobes.csv", "modes.toml", "lobes.png"))  # fmt: skip


def _judged_cuts(campaign: Campaign, runs: list[LoadedRun]) -> tuple[list, list[dict[str, Any]]]:
    """Each cut judged by the chatter detector: (rpm, depth, chatter) and a row for the table."""
    from analysis.chatter import detect_run

    verdicts, cut_rows = [], []
    for r in runs:
        rc = detect_run(r.run, campaign.spec.chatter.settings())
        n, d = float(r.conditions["spindle_rpm"]), float(r.conditions["depth_mm"])
        verdicts.append((n, d, rc.chatter))
        cut_rows.append({"run": r.index, "spindle_rpm": n, "depth_mm": d, "chatter": rc.chatter,
                         "chatter_hz": rc.frequency_hz if rc.chatter else math.nan,
                         "energy_ratio": rc.whole.energy_ratio,
                         "opr_ratio": rc.whole.opr_ratio})  # fmt: skip
    return verdicts, cut_rows
