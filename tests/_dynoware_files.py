"""Kistler DynoWare-style exports of end-mill slot cuts, written by hand for the import tests.

Independent of cutlab's analysis code on purpose (numpy only): the forces come from Altintas'
mechanistic model written out here, so a fit that recovers ``TRUTH`` checks the importer, the
axis mapping, the reduction and the fit against a separate derivation.

Model (Altintas, Manufacturing Automation, ch. 2): per axial slice db of a tooth at angle phi
(measured clockwise from +y towards +x, the feed direction; chip h = fz sin(phi) for
0 < phi < pi in a slot),

    dFt = (Ktc h + Kte) db,   dFr = (Krc h + Kre) db,   dFa = (Kac h + Kae) db,

and the force on the tool is Fx = -Ft cos(phi) - Fr sin(phi), Fy = Ft sin(phi) - Fr cos(phi).
A table dynamometer measures the force on the workpiece, the opposite; along the tool axis
cutlab's z takes +Fa (its stated convention). The helix delays slice z by z tan(helix) / R. The
signal is averaged over sub-samples (an integrate-and-sample ADC), so the engagement's edges do
not bias the revolution mean.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

#: Al 7075-T6 (Altintas, Manufacturing Automation, Table 2.1 style values): N/mm^2 and N/mm.
TRUTH = {"Ktc": 796.0, "Krc": 168.0, "Kac": 222.0, "Kte": 27.7, "Kre": 30.8, "Kae": 1.8}

#: The user's own cutter, in a catalogue next to the data (not in the shipped configs).
TOOLS_TOML = """\
[tools.lab-phi25-2f]
kind = "flat"
description = "phi 25 two-flute end mill of the lab"
diameter_mm = 25.0
flute_length_mm = 40.0
flutes = 2
helix_deg = 30.0
stickout_mm = 80.0
"""
TOOL = "lab-phi25-2f"
DIAMETER_MM, TEETH, HELIX_DEG = 25.0, 2, 30.0
RPM, AP_MM, RATE_HZ = 6000.0, 3.0, 10_000.0
FEEDS_MM_MIN = (300.0, 600.0, 1000.0, 1500.0)


def slot_forces(
    t_s: np.ndarray, fz_mm: float, ap_mm: float = AP_MM, rpm: float = RPM, coef=TRUTH,
    slices: int = 24, sub: int = 8, ae_mm: float = DIAMETER_MM,
) -> np.ndarray:  # fmt: skip
    """Workpiece force (n, 3) N, cutlab x (feed), y, z (tool axis), at sample times ``t_s``;
    a slot, or with ``ae_mm`` < D down milling (engaged from pi - arccos(1 - 2 ae / D) to pi)."""
    r = DIAMETER_MM / 2
    dt = 1.0 / RATE_HZ
    db = ap_mm / slices
    lag = (np.arange(slices) + 0.5) * db * np.tan(np.radians(HELIX_DEG)) / r
    entry = np.pi - np.arccos(1 - 2 * ae_mm / DIAMETER_MM)
    out = np.zeros((len(t_s), 3))
    for s in range(sub):  # sub-samples across each sample period
        phi0 = 2 * np.pi * rpm / 60.0 * (t_s + (s + 0.5) / sub * dt)
        for j in range(TEETH):
            phi = (phi0[:, None] + j * 2 * np.pi / TEETH - lag[None, :]) % (2 * np.pi)
            on = (phi > entry) & (phi < np.pi)  # a slot: from 0 to pi
            h = fz_mm * np.sin(phi)
            ft = np.where(on, coef["Ktc"] * h + coef["Kte"], 0.0) * db
            fr = np.where(on, coef["Krc"] * h + coef["Kre"], 0.0) * db
            fa = np.where(on, coef["Kac"] * h + coef["Kae"], 0.0) * db
            tool_x = -ft * np.cos(phi) - fr * np.sin(phi)
            tool_y = ft * np.sin(phi) - fr * np.cos(phi)
            out[:, 0] -= tool_x.sum(axis=1) / sub
            out[:, 1] -= tool_y.sum(axis=1) / sub
            out[:, 2] += fa.sum(axis=1) / sub
    return out


def slot_record(
    feed_mm_min: float, cut_s: float = 1.0, air_s: float = 0.3, offset_n=(4.0, -3.0, 2.0),
    noise_n: float = 1.0, seed: int = 0, ae_mm: float = DIAMETER_MM,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """(time s, force (n, 3) N in cutlab x, y, z): air, a steady slot, air (``air_s`` 0: the
    steady cut only), plus the amplifier's offset and white noise."""
    rng = np.random.default_rng(seed)
    n_air, n_cut = int(air_s * RATE_HZ), int(cut_s * RATE_HZ)
    t = np.arange(2 * n_air + n_cut) / RATE_HZ
    f = np.zeros((len(t), 3))
    fz = feed_mm_min / (RPM * TEETH)
    f[n_air : n_air + n_cut] = slot_forces(t[n_air : n_air + n_cut], fz, ae_mm=ae_mm)
    f += np.asarray(offset_n) + rng.normal(0.0, noise_n, f.shape)
    return t, f


def to_columns(force: np.ndarray, axes: str) -> dict[str, np.ndarray]:
    """The file's columns for a mapping ``x=-Fy,y=Fx,z=-Fz`` (cutlab axis = signed column), i.e.
    the inverse: each column = sign x the cutlab force it becomes."""
    cols = {}
    for item in axes.split(","):
        ax, src = item.split("=")
        sign = -1.0 if src.startswith("-") else 1.0
        cols[src.lstrip("-")] = sign * force[:, "xyz".index(ax)]
    return dict(sorted(cols.items()))


def write_export(
    path: Path, t_s: np.ndarray, columns: Mapping[str, np.ndarray], header: Mapping[str, object],
    *, sep: str = "\t", decimal: str = ".", header_sep: str = ":\t", units: bool = True,
    time_name: str = "Time", force_unit: str = "N",
) -> Path:  # fmt: skip
    """A DynoWare-style ASCII export: a header block of ``key<header_sep>value`` lines, the
    column-name row, a units row, then the samples (``decimal`` ',' as a German Windows writes
    them)."""

    def num(v: float) -> str:
        s = f"{v:.6f}".rstrip("0").rstrip(".") if isinstance(v, float) else str(v)
        return s.replace(".", decimal)

    lines = [f"DynoWare{header_sep}Type 5697A1", f"Sampling rate{header_sep}{num(RATE_HZ)}"]
    lines += [f"{k}{header_sep}{num(v) if isinstance(v, float) else v}" for k, v in header.items()]
    lines += ["", sep.join([time_name, *columns])]
    if units:
        lines.append(sep.join(["s"] + [force_unit] * len(columns)))
    data = np.column_stack([t_s, *columns.values()])
    for row in data:
        lines.append(sep.join(f"{v:.6f}".replace(".", decimal) for v in row))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def write_slot_exports(
    folder: Path, axes: str = "x=Fx,y=Fy,z=Fz", feeds: Sequence[float] = FEEDS_MM_MIN,
    header: bool = True, **kw,
) -> list[Path]:  # fmt: skip
    """One export per feed, ``cut_<feed>.txt``: columns so that ``axes`` maps them to cutlab's
    frame; with ``header`` its conditions in DynoWare ``key:\\tvalue`` lines. ``kw``:
    ``slot_record`` (air_s, offset_n...) and ``write_export`` (sep, decimal...) options."""
    rec = {k: kw.pop(k) for k in ("cut_s", "air_s", "offset_n", "noise_n", "ae_mm") if k in kw}
    out = []
    for k, feed in enumerate(feeds):
        t, f = slot_record(feed, seed=k, **rec)
        ae = rec.get("ae_mm", DIAMETER_MM)
        hdr = {"spindle_rpm": RPM, "feed_mm_min": feed, "ap_mm": AP_MM, "ae_mm": ae,
               "mode": "slot" if ae == DIAMETER_MM else "down"} if header else {}  # fmt: skip
        p = folder / f"cut_{int(feed)}.txt"
        out.append(write_export(p, t, to_columns(f, axes), hdr, **kw))
    return out


def conditions_csv(path: Path, files: Sequence[Path], sep: str = ",", extra: str = "") -> Path:
    """A conditions table, one row per export (by name without extension)."""
    head = ["file", "spindle_rpm", "feed_mm_min", "ap_mm", "ae_mm", "teeth", "tool"]
    rows = [sep.join(head) + (sep + extra.split("=")[0] if extra else "")]
    for p in files:
        feed = p.stem.split("_")[1]
        cells = [p.stem, f"{RPM:g}", feed, f"{AP_MM:g}", f"{DIAMETER_MM:g}", str(TEETH), TOOL]
        rows.append(sep.join(cells) + (sep + extra.split("=")[1] if extra else ""))
    path.write_text("\n".join(rows) + "\n")
    return path
