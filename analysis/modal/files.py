"""An impulse-hammer test from a file: a run file (.h5) or a DynoWare / CSV export with a hammer
channel, analysed into modes (`cutlab analyze modal`).

A response column's unit says what it measures, in its name (``ax [m/s^2]``, ``dx (mm)``):
force (N, kN, lbf: a dynamometer), displacement (m, mm, um) or acceleration (m/s^2, g); a column
without a unit is taken as ``response`` (force unless told). A run file's channels are forces.

A file with no header row at all (as many data loggers write a tap test: time, hammer N, accel
m/s^2, one row per sample) is read with ``columns`` naming its columns in order, units in
brackets (``time[s],hammer[N],accel[m/s^2]``); the rate comes from the time column or ``rate_hz``.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import cast

import numpy as np
import pandas as pd

from analysis.config import load_rig
from analysis.errors import AnalysisError
from analysis.modal.hammer import (
    RESPONSES,
    ImpactRecord,
    ModalResult,
    ModeEstimate,
    modal_analysis,
    tooth_passing_warnings,
)
from analysis.modal.plot import plot_frf
from analysis.output import table_lines
from analysis.runs import FORCE_UNIT_TO_N, load_run, read_force_table
from analysis.validation import JsonObject, JsonValue

__all__ = ["hammer_file_record", "modal_file"]

_TIME_COLUMNS = ("time", "time_s", "zeit")
#: Response units (lower case) -> (kind, factor to SI).
_UNITS = {
    **{u: ("force", f) for u, f in FORCE_UNIT_TO_N.items()},
    "m": ("disp", 1.0), "mm": ("disp", 1e-3), "um": ("disp", 1e-6), "\u00b5m": ("disp", 1e-6),
    "\u03bcm": ("disp", 1e-6), "m/s^2": ("accel", 1.0), "m/s2": ("accel", 1.0),
    "m/s\u00b2": ("accel", 1.0), "m/s/s": ("accel", 1.0), "g": ("accel", 9.80665),
}  # fmt: skip


def _response_column(
    path: str | Path, name: str, unit: str, response: str | None
) -> tuple[str, float]:
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


def parse_columns(spec: str | Sequence[str]) -> tuple[list[str], list[str]]:
    """Column names and units of ``--columns``: ``time[s],hammer[N],accel[m/s^2]`` (or a list)."""
    items = spec.split(",") if isinstance(spec, str) else list(spec)
    names, units = [], []
    for item in items:
        m = re.match(r"^\s*([^\[\]()]+?)\s*(?:[\[(]\s*([^\])]*?)\s*[\])])?\s*$", item)
        if not m or not m.group(1):
            raise AnalysisError(
                f"--columns {item!r}: expected a column name with an optional unit in brackets, "
                "e.g. time[s],hammer[N],accel[m/s^2]"
            )
        names.append(m.group(1))
        units.append(m.group(2) or "")
    if len(set(n.lower() for n in names)) != len(names):
        raise AnalysisError(f"--columns {','.join(items)}: a column name appears twice")
    return names, units


def _headerless(path: Path, names: list[str], units: list[str]) -> tuple[np.ndarray, float]:
    """Samples of a file without a header row, in ``names``' order, and the rate from a time
    column (NaN without one)."""
    try:
        first = next((ln for ln in path.open(encoding="utf-8", errors="replace") if ln.strip()), "")
    except OSError as exc:
        raise AnalysisError(f"{path}: cannot read: {exc}") from None
    sep = next((c for c in ("\t", ";", ",") if c in first), r"\s+")
    decimal = "," if sep in ("\t", ";", r"\s+") and re.search(r"\d,\d", first) else "."
    try:
        df = pd.read_csv(path, sep=sep, header=None, decimal=decimal, skip_blank_lines=True,
                         engine="python" if sep == r"\s+" else "c")  # fmt: skip
    except (ValueError, pd.errors.ParserError, UnicodeDecodeError) as exc:
        raise AnalysisError(f"{path}: cannot read the samples: {exc}") from None
    if df.shape[1] != len(names):
        raise AnalysisError(
            f"{path}:1: {df.shape[1]} data columns but --columns names {len(names)} "
            f"({','.join(names)})"
        )
    data = df.apply(pd.to_numeric, errors="coerce").to_numpy(float)
    bad = np.argwhere(~np.isfinite(data))
    if bad.size:
        r, c = bad[0]
        what = (
            "a header row? (a headerless file has numbers only)"
            if r == 0
            else "not a finite number"
        )
        raise AnalysisError(f"{path}:{r + 1}: column {names[c]} = {df.iat[r, c]!r}: {what}")
    lower = [n.lower() for n in names]
    t = next((k for k, n in enumerate(lower) if n in _TIME_COLUMNS), None)
    if t is None or len(data) < 3:
        return data, float("nan")
    dt = np.diff(data[:, t])
    scale = {"": 1.0, "s": 1.0, "ms": 1e-3, "us": 1e-6}.get(units[t].lower())
    if scale is None:
        raise AnalysisError(f"--columns {names[t]}[{units[t]}]: expected a time unit s, ms or us")
    if np.any(dt <= 0):
        raise AnalysisError(f"{path}: the time column {names[t]} does not increase")
    return data, 1.0 / (float(np.median(dt)) * scale)


def hammer_file_record(
    path: str | Path, hammer: str = "hammer", rate_hz: float | None = None,
    response: str | None = None, columns: str | Sequence[str] | None = None,
) -> ImpactRecord:  # fmt: skip
    """The hammer channel (named ``hammer``, any case) and the other channels but time as
    responses (axis letters x, y, z where a name ends in one), in SI units with their kind from
    the column's unit, else ``response`` (``RESPONSES``; default force); ``rate_hz`` replaces an
    export's rate (a run file's own rate is kept); ``columns`` names the columns of a file
    without a header row (:func:`parse_columns`)."""
    path = Path(path)
    if response is not None and response not in RESPONSES:
        raise AnalysisError(f"response = {response!r}: expected one of {', '.join(RESPONSES)}")
    if rate_hz is not None and not 0 < rate_hz < 1e8:
        raise AnalysisError(f"--rate {rate_hz:g}: expected a sampling rate > 0 Hz")
    if columns is not None and path.suffix.lower() not in (".h5", ".hdf5"):
        columns, units = parse_columns(columns)
        data, rate = _headerless(path, columns, units)
        if rate_hz:
            rate = rate_hz
    elif path.suffix.lower() in (".h5", ".hdf5"):
        run = load_run(path)
        data = run.force_n if run.force_n is not None else run.volts
        columns, rate = list(run.channel_names), run.rate_hz
        units = [""] * len(columns)
    else:
        try:
            t = read_force_table(path)
        except AnalysisError as exc:
            if "column-name row" not in str(exc):
                raise
            raise AnalysisError(
                f"{path}: no header row naming the columns: give them in order with --columns, "
                "e.g. --columns time[s],hammer[N],accel[m/s^2]"
            ) from None
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


def _mode_row(m: ModeEstimate, n_hits: int) -> JsonObject:
    """One mode's JSON row: coherence only from 2 hits on; a force response's share of the
    static gain, else the modal stiffness, mass and damping."""
    row: JsonObject = {
        "axis": m.channel,
        "frequency_hz": m.frequency_hz,
        "damping_ratio": m.damping_ratio,
        "damping_windowed": m.damping_windowed,
        "half_power_frequency_hz": m.half_power_frequency_hz,
        "half_power_damping": m.half_power_damping,
        "coherence": m.coherence if n_hits > 1 else None,
        "response": m.response,
        "stable_poles": m.stable_poles,
        "frequency_hz_uncertainty": m.frequency_uncertainty_hz,
        "damping_ratio_uncertainty": m.damping_uncertainty,
    }
    if n_hits == 1:
        row["coherence_reason"] = "one hit: coherence needs at least 2"
    if m.response == "force":
        row["static_gain_share"] = m.residue / (2 * np.pi * m.frequency_hz) ** 2
    else:
        row.update(stiffness_n_m=m.stiffness_n_m, mass_kg=m.mass_kg,
                   damping_n_s_m=m.damping_n_s_m)  # fmt: skip
    return row


def _stabilisation_plot(path: str | Path, res: ModalResult, png: str | Path) -> Path:
    """The stabilisation diagram of the analysed channels, their chosen modes marked."""
    from analysis.modal.stabilisation import plot_stabilisation

    if not res.stabilisation:
        raise AnalysisError(
            f"{path}: no channel was analysed ({'; '.join(r for _, r in res.skipped)}): "
            "no stabilisation diagram"
        )
    frfs = {n: res.frf[res.channels.index(n)] for n in res.stabilisation}
    chosen = {n: [m.frequency_hz for m in res.modes if m.channel == n] for n in frfs}
    return plot_stabilisation(res.stabilisation, frfs, res.freq_hz, chosen, png)


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
    columns: str | Sequence[str] | None = None,
) -> JsonObject:
    """Modes of a hammer-test file as a JSON-able dict: hits used and double, modes per axis
    (with modal stiffness, mass and damping for a displacement or acceleration response, a
    force response's share of the static gain otherwise), skipped channels, the rig config's
    modes, warnings (the analysis's and, for planned ``spindle_rpm`` with ``teeth``,
    tooth-passing harmonics near a mode); with ``plot_png`` the FRF plot, with
    ``stabilisation_png`` the stabilisation diagram, with ``save`` the modes file
    (:func:`~analysis.modal.modes.save_modes`) written."""
    from analysis.modal.modes import save_modes

    if not 1 <= teeth <= 1000:
        raise AnalysisError(f"--teeth {teeth}: expected 1 to 1000 teeth")
    rec = hammer_file_record(path, hammer, rate_hz, response, columns)
    res = modal_analysis(rec, record_s=record_s, window_end=window_end)
    rig = load_rig(rig_path or None)
    warn: list[JsonValue] = list(res.warnings)
    if spindle_rpm:
        warn += tooth_passing_warnings(res.modes, spindle_rpm, teeth)
    modes: list[JsonValue] = [_mode_row(m, len(res.hits_used)) for m in res.modes]
    out: JsonObject = {
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
        out["stabilisation_plot"] = str(_stabilisation_plot(path, res, stabilisation_png))
    if save:
        saved, notes = save_modes(save, res.modes, source=Path(path).name)
        out["saved"] = str(saved)
        warn += notes  # the list out["warnings"] holds
    return out


def modal_lines(out: Mapping[str, JsonValue]) -> list[str]:
    """``cutlab analyze modal``'s text: :func:`modal_file`'s modes as a table, then each channel
    skipped and why."""
    modes = cast("list[Mapping[str, object]]", out["modes"])
    skipped = cast("list[Mapping[str, object]]", out["skipped"])
    return [*table_lines(modes), *(f"skipped {s['channel']}: {s['reason']}" for s in skipped)]
