"""Exports of end-mill cuts made by the independent simulator (tests/_force_sim.py, which imports
no fitting code) for the fit-trust and axes tests: a tool whose cutting pressures rise above its
max chip thickness, as the twin's chip breaker does (rig/sim/_regen.py: x (1 + 3 (h / h_max - 1))
on K_tc, K_rc, K_ac), and tab-separated exports with the conditions in header lines."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tests._force_sim import Cut, Law, Record, simulate

TRUTH = dict(Ktc_n_mm2=796.0, Krc_n_mm2=168.0, Kac_n_mm2=222.0, Kte_n_mm=27.7, Kre_n_mm=30.8,
             Kae_n_mm=1.8)  # fmt: skip
RATE_HZ = 10_000.0
RPM = 3000.0
DEPTH_MM = 2.0
MAX_CHIP_MM = 0.08  # phi10-flat's max_chip_mm in configs/tools.toml
OVERLOAD_GAIN = 3.0  # EndMill.overload_gain's default


def law(fz_mm: float) -> Law:
    """The linear law, its cutting pressures raised above the max chip (a slot's h_max = fz)."""
    gain = 1 + OVERLOAD_GAIN * max(fz_mm / MAX_CHIP_MM - 1, 0.0)
    c = dict(TRUTH)
    for k in ("Ktc_n_mm2", "Krc_n_mm2", "Kac_n_mm2"):
        c[k] *= gain
    return Law("linear", c)


def record(fz_mm: float, mode: str = "slot", ae_mm: float = 10.0, seed: int = 0) -> np.ndarray:
    """Workpiece force (n, 3) N in the simulator's X (feed), Y, Z (up) of one cut."""
    entry, exit_ = Cut.immersion(ae_mm, 10.0, mode)
    cut = Cut(fz_mm=fz_mm, depth_mm=DEPTH_MM, spindle_rpm=RPM, entry_rad=entry, exit_rad=exit_)
    rec = Record(rate_hz=RATE_HZ, air_revs=4, ramp_revs=2, steady_revs=24, slices=6,
                 noise_n=1.0, seed=seed)  # fmt: skip
    return simulate(cut, law(fz_mm), rec)[1]


def write(path: Path, force: np.ndarray, header: dict, columns=("Fx", "Fy", "Fz"),
          matrix: np.ndarray | None = None) -> Path:  # fmt: skip
    """A tab-separated export; the columns hold ``matrix @ force`` (default the identity: the
    dynamometer's axes are the simulator's)."""
    cols = force @ (np.eye(3) if matrix is None else matrix).T
    lines = [f"Sampling rate:\t{RATE_HZ:g}"] + [f"{k}:\t{v}" for k, v in header.items()]
    lines += ["", "\t".join(("Time", *columns)), "\t".join(["s"] + ["N"] * 3)]
    t = np.arange(len(cols)) / RATE_HZ
    lines += ["\t".join(f"{v:.5f}" for v in row) for row in np.column_stack([t, cols])]
    path.write_text("\n".join(lines) + "\n")
    return path


def export(folder: Path, fz_mm: float, mode: str = "slot", ae_mm: float = 10.0, seed: int = 0,
           matrix: np.ndarray | None = None) -> Path:  # fmt: skip
    """One cut as an export named for its conditions, tool phi10-flat."""
    hdr = {"spindle_rpm": f"{RPM:g}", "fz_mm": f"{fz_mm:g}", "depth_mm": f"{DEPTH_MM:g}",
           "width_mm": f"{ae_mm:g}", "mode": mode, "tool": "phi10-flat"}  # fmt: skip
    name = f"{mode}_ae{ae_mm:g}_fz{fz_mm:g}.txt"
    return write(folder / name, record(fz_mm, mode, ae_mm, seed), hdr, matrix=matrix)
