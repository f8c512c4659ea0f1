"""Validation: predict other runs with identified coefficients and compare with what was measured.

Seed 003 Figs 5-14 compare predicted and measured T and R forces against depth of cut at other
feeds per tooth. Here each reduced run (``RunAverage``) is predicted with the model and compared
on the mean force per revolution in the dynamometer axes (which the dynamometer's modes and the
unknown angular phase do not change) and on the peak of the revolution-averaged resultant (which
the modes do change: the prediction is passed through them when a dynamometer is given).

``compare_runs(averages, tool, coefficients, dynamometer=None) -> Comparison`` gives a table
(one row per run: conditions, measured and predicted mean X, Y, Z and resultant, errors in % of
the measured mean resultant); ``Comparison.to_frame()`` is the pandas view; ``plot_comparison``
writes PNGs: mean forces against depth of cut per feed (like seed 003 Figs 7-12) and the
averaged waveforms measured vs predicted.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, TypedDict

import numpy as np
import numpy.typing as npt

from analysis.config import (
    Dynamometer,
    EndMill,
    EndMillCoefficients,
    FaceMill,
    FaceMillCoefficients,
)
from analysis.errors import AnalysisError
from analysis.forces.models import FACEMILL, model_for
from analysis.identify._common import RunAverage, RunConditions

if TYPE_CHECKING:
    import pandas as pd

    from analysis.modal import DynamometerFilter

__all__ = ["Comparison", "ComparisonRow", "compare_runs", "plot_comparison", "plot_waveforms",
           "predicted_mean"]  # fmt: skip


def predicted_mean(
    c: RunConditions, tool: FaceMill | EndMill, coef: FaceMillCoefficients | EndMillCoefficients
) -> np.ndarray:
    """Mean force per revolution (3,) N predicted for a run's conditions."""
    try:
        model = model_for(tool)
    except AnalysisError:
        raise AnalysisError(
            f"tool of kind {getattr(tool, 'kind', '?')!r} cannot be predicted"
        ) from None
    return model.mean_design(tool, model.cut(tool, c)) @ model.coefficient_vector(coef)


class ComparisonRow(TypedDict):
    """One run of a :class:`Comparison` (N, %)."""

    run: str
    fz_mm: float
    depth_mm: float
    measured_mean_n: npt.NDArray[np.float64]
    predicted_mean_n: npt.NDArray[np.float64]
    measured_resultant_n: float
    predicted_resultant_n: float
    error_pct: npt.NDArray[np.float64]
    resultant_error_pct: float
    measured_peak_n: float
    predicted_peak_n: float


@dataclass(frozen=True)
class Comparison:
    """Predicted vs measured per run. ``rows``: one dict per run with name, fz_mm, depth_mm,
    measured/predicted mean X, Y, Z and resultant (N), ``error_pct`` (3,) per axis in % of the
    measured mean resultant, ``resultant_error_pct``, peak resultant measured/predicted (N).
    ``max_error_pct``: largest per-axis error over the runs."""

    rows: tuple[ComparisonRow, ...]
    max_error_pct: float

    def to_frame(self) -> pd.DataFrame:
        import pandas as pd

        flat = []
        for r in self.rows:
            d: dict[str, object] = {k: v for k, v in r.items() if not isinstance(v, np.ndarray)}
            for i, ax in enumerate("xyz"):
                d[f"measured_{ax}_n"] = float(r["measured_mean_n"][i])
                d[f"predicted_{ax}_n"] = float(r["predicted_mean_n"][i])
                d[f"error_{ax}_pct"] = float(r["error_pct"][i])
            flat.append(d)
        return pd.DataFrame(flat)


def compare_runs(
    averages: Sequence[RunAverage],
    tool: FaceMill | EndMill,
    coef: FaceMillCoefficients | EndMillCoefficients,
    dynamometer: Dynamometer | DynamometerFilter | None = None,
) -> Comparison:
    """Predict each run and compare with its measurement (see module docstring)."""
    rows: list[ComparisonRow] = []
    for a in averages:
        pred = predicted_mean(a.conditions, tool, coef)
        meas = a.mean_n
        scale = max(float(np.linalg.norm(meas)), 1e-9)
        err = (pred - meas) / scale * 100
        peak_meas = float(np.linalg.norm(a.waveform_n, axis=1).max())
        peak_pred = float("nan")
        if FACEMILL.describes(tool) and isinstance(coef, FaceMillCoefficients):
            from analysis.identify.facemill import predicted_waveform

            # The peak of the resultant does not depend on the run's unknown phase.
            wave = predicted_waveform(a, tool, coef, dynamometer)
            peak_pred = float(np.linalg.norm(wave, axis=1).max())
        rows.append(
            {
                "run": a.name,
                "fz_mm": a.conditions.fz_mm,
                "depth_mm": a.conditions.depth_mm,
                "measured_mean_n": meas,
                "predicted_mean_n": pred,
                "measured_resultant_n": float(np.linalg.norm(meas)),
                "predicted_resultant_n": float(np.linalg.norm(pred)),
                "error_pct": err,
                "resultant_error_pct": float(
                    (np.linalg.norm(pred) - np.linalg.norm(meas)) / scale * 100
                ),
                "measured_peak_n": peak_meas,
                "predicted_peak_n": peak_pred,
            }
        )
    worst = max((float(np.abs(r["error_pct"]).max()) for r in rows), default=0.0)
    return Comparison(tuple(rows), worst)


#: which condition a comparison plot puts on its x axis: the one the runs vary most over
_SWEEP_KEYS = (("fz_mm", "feed per tooth, mm"), ("depth_mm", "axial depth of cut, mm"),
               ("width_mm", "width of cut, mm"))  # fmt: skip


def _swept(base: RunConditions, key: str, value: float) -> RunConditions:
    """``base`` with the swept condition ``key`` (one of _SWEEP_KEYS) at ``value``."""
    if key == "fz_mm":
        return replace(base, fz_mm=value)
    if key == "depth_mm":
        return replace(base, depth_mm=value)
    return replace(base, width_mm=value)


def plot_comparison(
    cmp: Comparison, out_dir: str | Path, stem: str = "validation",
    tool: FaceMill | EndMill | None = None,
    coef: FaceMillCoefficients | EndMillCoefficients | None = None,
    conditions: Sequence[RunConditions] | None = None,
) -> list[Path]:  # fmt: skip
    """PNG: mean X, Y, Z force per revolution against the condition the runs vary most over
    (feed per tooth for a feed sweep, depth for a depth sweep), measured (markers) and, with
    ``tool``, ``coef`` and the runs' ``conditions``, the model's line through them; below, each
    run's residual (measured - predicted) per direction. The title quotes the table's figure
    (the largest resultant error, % of the measured resultant). Returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = list(cmp.rows)
    cond = list(conditions) if conditions is not None else None
    vals = [{"fz_mm": float(r["fz_mm"]), "depth_mm": float(r["depth_mm"]),
             "width_mm": float(cond[i].width_mm) if cond is not None else float("nan")}
            for i, r in enumerate(rows)]  # fmt: skip

    def distinct(k: str) -> int:
        return len({v[k] for v in vals if np.isfinite(v[k])})

    key, label = max(_SWEEP_KEYS, key=lambda kl: distinct(kl[0]))
    others = [k for k, _ in _SWEEP_KEYS if k != key and distinct(k)]

    def x_of(i: int) -> float:
        return vals[i][key]

    def group_of(i: int) -> tuple[float, ...]:
        return tuple(round(vals[i][k], 6) for k in others)

    groups = sorted({group_of(i) for i in range(len(rows))})
    fig, axes = plt.subplots(2, 3, figsize=(13, 6.5), constrained_layout=True,
                             gridspec_kw={"height_ratios": [2.2, 1]}, sharex="col")  # fmt: skip
    for j, g in enumerate(groups):
        idx = sorted((i for i in range(len(rows)) if group_of(i) == g), key=x_of)
        xs = np.array([x_of(i) for i in idx])
        name = ", ".join(f"{k.removesuffix('_mm')} {v:g} mm" for k, v in zip(others, g))
        col = f"C{j}"
        line = None
        if tool is not None and coef is not None and cond is not None and len(idx):
            grid = np.linspace(0, xs.max() * 1.1, 40)[1:]
            base = cond[idx[0]]
            line = np.array([predicted_mean(_swept(base, key, float(x)), tool, coef)
                             for x in grid])  # fmt: skip
        for a in range(3):
            ax = axes[0, a]
            ax.plot(xs, [rows[i]["measured_mean_n"][a] for i in idx], "o", color=col,
                    label=f"measured ({name})" if name else "measured")  # fmt: skip
            if line is not None:
                ax.plot(grid, line[:, a], "-", color=col, lw=1,
                        label=f"model ({name})" if name else "model")  # fmt: skip
            else:
                ax.plot(xs, [rows[i]["predicted_mean_n"][a] for i in idx], "x--", color=col,
                        lw=0.8, label="predicted")  # fmt: skip
            res = [rows[i]["measured_mean_n"][a] - rows[i]["predicted_mean_n"][a] for i in idx]
            axes[1, a].plot(xs, res, "o", color=col)
    for a in range(3):
        axes[0, a].set_ylabel(f"mean F{'xyz'[a]} per revolution, N")
        axes[0, a].grid(True, alpha=0.3)
        axes[0, a].axhline(0, color="0.6", lw=0.6)
        axes[1, a].axhline(0, color="0.3", lw=0.8)
        axes[1, a].set_ylabel(f"residual F{'xyz'[a]}, N")
        axes[1, a].set_xlabel(label)
        axes[1, a].grid(True, alpha=0.3)
        axes[0, a].set_xlim(left=0)
    axes[0, 0].legend(fontsize=7)
    worst = max((abs(r["resultant_error_pct"]) for r in rows), default=0.0)
    fig.suptitle(f"predicted vs measured, {len(rows)} runs: largest resultant error {worst:.2f} % "
                 f"(the table's error_pct); largest per-direction error {cmp.max_error_pct:.2f} % "
                 "of the resultant")  # fmt: skip
    path = out / f"{stem}_mean_forces.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return [path]


def plot_waveforms(
    averages: Sequence[RunAverage], tool: FaceMill, coef: FaceMillCoefficients,
    out_dir: str | Path, dynamometer: Dynamometer | DynamometerFilter | None = None,
    stem: str = "waveforms", max_runs: int = 6,
) -> list[Path]:  # fmt: skip
    """PNG: each run's revolution-averaged X, Y, Z force, measured vs predicted (face mills; the
    prediction goes through the dynamometer's modes and is aligned to the run's phase)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from analysis.identify.facemill import _filter_for, _phase, predicted_waveform

    if not FACEMILL.describes(tool):
        raise AnalysisError("waveform plots need the face-mill model (end mills: mean forces)")
    runs = list(averages)[:max_runs]
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(len(runs), 1, figsize=(10, 2.4 * len(runs)), squeeze=False,
                             constrained_layout=True)  # fmt: skip
    for ax, a in zip(axes[:, 0], runs):
        filt = _filter_for(dynamometer, a.rate_hz)
        phase = _phase(a, tool, filt)
        pred = predicted_waveform(a, tool, coef, filt, phase)
        ang = np.degrees(phase + 2 * np.pi * np.arange(len(a.waveform_n)) / len(a.waveform_n))
        ang = ang % 360
        order = np.argsort(ang)
        for i, name in enumerate("XYZ"):
            # measured thick and pale, the prediction thin and dark on top: both stay visible
            ax.plot(ang[order], a.waveform_n[order, i], color=f"C{i}", lw=2.6, alpha=0.35,
                    label=f"F{name} measured")  # fmt: skip
            ax.plot(ang[order], pred[order, i], color=f"C{i}", lw=1.0, ls="--",
                    label=f"F{name} predicted")  # fmt: skip
        # the cut's angular span (where the resultant exceeds 5 % of its peak), with margins:
        # a face mill's insert cuts over a part of the turn, the rest is air
        res = np.linalg.norm(a.waveform_n[order], axis=1)
        cutting = ang[order][res > 0.05 * res.max()]
        if cutting.size and np.ptp(cutting) < 300:
            lo, hi = cutting.min(), cutting.max()
            pad = max(10.0, 0.15 * (hi - lo))
            ax.set_xlim(max(0.0, lo - pad), min(360.0, hi + pad))
        ax.set_title(f"{a.name}: fz {a.conditions.fz_mm:g} mm, depth {a.conditions.depth_mm:g} "
                     "mm (thick: measured, dashed: predicted)", fontsize=9)  # fmt: skip
        ax.set_ylabel("N")
        ax.grid(True, alpha=0.3)
    axes[-1, 0].set_xlabel("insert angle, deg")
    axes[0, 0].legend(fontsize=7, ncol=3)
    axes[-1, 0].set_xlabel("insert angle, deg (zoomed to the cut)")
    if len(runs) < len(averages):
        fig.suptitle(f"{len(runs)} of {len(averages)} runs shown", fontsize=9)
    path = out / f"{stem}.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return [path]
