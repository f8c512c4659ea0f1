"""An impulse-hammer test from a file: a run file (.h5) or a DynoWare / CSV export with a hammer
channel, analysed into modes (`cutlab analyze modal`).

A response column's unit says what it measures, in its name (``ax [m/s^2]``, ``dx (mm)``):
force (N, kN, lbf: a dynamometer), displacement (m, mm, um) or acceleration (m/s^2, g); a column
without a unit is taken as ``response`` (force unless told). A run file's channels are forces.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from analysis.config import load_rig
from analysis.errors import AnalysisError
from analysis.modal.hammer import (
    RESPONSES,
    ImpactRecord,
    modal_analysis,
    plot_frf,
    tooth_passing_warnings,
)
from analysis.runs import FORCE_UNIT_TO_N, load_run, read_force_table

__all__ = ["hammer_file_record", "modal_file"]

_TIME_COLUMNS = ("time", "time_s", "zeit")
#: Response units (lower case) -> (kind, factor to SI).
_UNITS = {
    **{u: ("force", f) for u, f in FORCE_UNIT_TO_N.items()},
    "m": ("disp", 1.0), "mm": ("disp", 1e-3), "um": ("disp", 1e-6), "\u00b5m": ("disp", 1e-6),
    "\u03bcm": ("disp", 1e-6), "m/s^2": ("accel", 1.0), "m/s2": ("accel", 1.0),
    "m/s\u00b2": ("accel", 1.0), "m/s/s": ("accel", 1.0), "g": ("accel", 9.80665),
}  # fmt: skip


def _response_column(path, name: str, unit: str, response: str | None) -> tuple[str, float]:
    """(kind, factor to SI) of one response column."""
    u = unit.strip().lower()
    if not u:
        return response or "force", 1.0
    if u not in _UNITS:
        if response in (None, "force"):
            return "force", 1.0  # volts or counts: a gain, which frequency and damping ignore
        raise AnalysisError(
            f"{path}: column {name} unit {unit!r}: expected m, mm, um (disp) or m/s^2, g "
            f"(accel) for --response {response}"
        )
    kind, factor = _UNITS[u]
    if response is not None and kind != response:
        raise AnalysisError(
            f"{path}: column {name} is in {unit} ({kind}) but --response is {response}"
        )
    return kind, factor


def hammer_file_record(
    path: str | Path, hammer: str = "hammer", rate_hz: float | None = None,
    response: str | None = None,
) -> ImpactRecord:  # fmt: skip
    """The hammer channel (named ``hammer``, any case) and the other channels but time as
    responses (axis letters x, y, z where a name ends in one), in SI units with their kind from
    the column's unit, else ``response`` (``RESPONSES``; default force); ``rate_hz`` replaces an
    export's rate (a run file's own rate is kept)."""
    path = Path(path)
    if response is not None and response not in RESPONSES:
        raise AnalysisError(f"response = {response!r}: expected one of {', '.join(RESPONSES)}")
    if rate_hz is not None and not 0 < rate_hz < 1e8:
        raise AnalysisError(f"--rate {rate_hz:g}: expected a sampling rate > 0 Hz")
    if path.suffix.lower() in (".h5", ".hdf5"):
        run = load_run(path)
        data = run.force_n if run.force_n is not None else run.volts
        columns, rate = list(run.channel_names), run.rate_hz
        units = [""] * len(columns)
    else:
        t = read_force_table(path)
        data, columns, rate, units = t.data, list(t.columns), t.rate_hz, list(t.units)
        if rate_hz:
            rate = rate_hz
    lower = [c.lower() for c in columns]
    if hammer.lower() not in lower:
        raise AnalysisError(
            f"{path}: no hammer channel {hammer!r} among {columns}; name it with --hammer"
        )
    if not np.isfinite(rate):
        raise AnalysisError(f"{path}: no sampling rate in the file; give --rate HZ")
    h = lower.index(hammer.lower())
    hu = units[h].strip().lower()
    if hu and hu not in FORCE_UNIT_TO_N:
        raise AnalysisError(f"{path}: hammer column {columns[h]} unit {units[h]!r}: expected N")
    resp = [k for k, c in enumerate(lower) if k != h and c not in _TIME_COLUMNS]
    if not resp:
        raise AnalysisError(f"{path}: no response channel beside the hammer among {columns}")
    names = tuple(lower[k][-1] if lower[k] and lower[k][-1] in "xyz" else columns[k] for k in resp)
    kinds, scale = zip(*(_response_column(path, columns[k], units[k], response) for k in resp))
    hammer_n = data[:, h] * FORCE_UNIT_TO_N.get(hu, 1.0)
    return ImpactRecord(hammer_n, data[:, resp] * np.array(scale), float(rate), names, path.stem,
                        tuple(kinds))  # fmt: skip


def modal_file(
    path: str | Path,
    hammer: str = "hammer",
    rate_hz: float | None = None,
    record_s: float = 0.08,
    window_end: float = 0.05,
    spindle_rpm: Sequence[float] | None = None,
    teeth: int = 1,
    rig_path: str | Path | None = None,
    plot_png: str | Path | None = None,
    response: str | None = None,
    stabilisation_png: str | Path | None = None,
    save: str | Path | None = None,
) -> dict[str, Any]:
    """Modes of a hammer-test file as a JSON-able dict: hits used and double, modes per axis
    (with modal stiffness, mass and damping for a displacement or acceleration response, a
    force response's share of the static gain otherwise), skipped channels, the rig config's
    modes, warnings (the analysis's and, for planned ``spindle_rpm`` with ``teeth``,
    tooth-passing harmonics near a mode); with ``plot_png`` the FRF plot, with
    ``stabilisation_png`` the stabilisation diagram, with ``save`` the modes file
    (:func:`~analysis.modal.modes.save_modes`) written."""
    from analysis.modal.modes import save_modes
    from analysis.modal.stabilisation import plot_stabilisation

    if not 1 <= teeth <= 1000:
        raise AnalysisError(f"--teeth {teeth}: expected 1 to 1000 teeth")
    rec = hammer_file_record(path, hammer, rate_hz, response)
    res = modal_analysis(rec, record_s=record_s, window_end=window_end)
    rig = load_rig(rig_path or None)
    warn = list(res.warnings)
    if spindle_rpm:
        warn += tooth_passing_warnings(res.modes, spindle_rpm, teeth)
    modes = []
    for m in res.modes:
        row = {
            "axis": m.channel,
            "frequency_hz": m.frequency_hz,
            "damping_ratio": m.damping_ratio,
            "damping_windowed": m.damping_windowed,
            "half_power_frequency_hz": m.half_power_frequency_hz,
            "half_power_damping": m.half_power_damping,
            "coherence": m.coherence,
            "response": m.response,
            "stable_poles": m.stable_poles,
        }
        if m.response == "force":
            row["static_gain_share"] = m.residue / (2 * np.pi * m.frequency_hz) ** 2
        else:
            row.update(stiffness_n_m=m.stiffness_n_m, mass_kg=m.mass_kg,
                       damping_n_s_m=m.damping_n_s_m)  # fmt: skip
        modes.append(row)
    out: dict[str, Any] = {
        "file": str(Path(path)),
        "hits_used": list(res.hits_used),
        "double_hits": list(res.double_hits),
        "modes": modes,
        "skipped": [{"channel": c, "reason": r} for c, r in res.skipped],
        "config_modes": [m.model_dump() for m in rig.dynamometer.modes],
        "warnings": warn,
    }
    if plot_png:
        out["plot"] = str(plot_frf(res, plot_png))
    if stabilisation_png:
        if not res.stabilisation:
            raise AnalysisError(
                f"{path}: no channel was analysed ({'; '.join(r for _, r in res.skipped)}): "
                "no stabilisation diagram"
            )
        frfs = {n: res.frf[res.channels.index(n)] for n in res.stabilisation}
        chosen = {n: [m.frequency_hz for m in res.modes if m.channel == n] for n in frfs}
        out["stabilisation_plot"] = str(plot_stabilisation(res.stabilisation, frfs, res.freq_hz,
                                                           chosen, stabilisation_png))  # fmt: skip
    if save:
        saved, notes = save_modes(save, res.modes, source=Path(path).name)
        out["saved"] = str(saved)
        out["warnings"] += notes
    return out
