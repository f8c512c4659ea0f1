"""What a machine and a tool can take: the limits a program is checked against, and the closed
forms behind them.

* Spindle: constant torque up to the base speed P / T, constant power above it (the rated curve
  of a spindle motor). Checking the cut's torque against T and its power against P separately is
  that curve: P <= T w below the base speed is the torque limit.
* Tool: the catalogue's largest chip thickness (``EndMill.max_chip_mm``), and the static
  deflection of the stick-out as a cantilever, d = F L^3 / (3 E I), I = pi d_e^4 / 64 with the
  fluted part's equivalent diameter d_e = 0.8 D (Kops & Vo, "Determination of the equivalent
  diameter of an end mill based on its compliance", CIRP Annals 39/1, 1990; Altintas,
  Manufacturing Automation, 2nd ed., 2012, 2.6). Taking d_e over the whole stick-out (shank
  included) errs on the safe side.
* Stability: the chatter-free axial depth at the programmed speed, from a lobes table
  (``cutlab analyze stability -o lobes.csv``: spindle_rpm, depth_limit_mm) interpolated in speed,
  or from the tool's modes (``EndMill.modes``) by :mod:`analysis.stability` at the cut's radial
  immersion; times a margin.

Units: N, mm, rpm, kW, N m; E in N/mm^2 (MPa).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis.config import EndMill, EndMillCoefficients, MachineConfig
from analysis.validation import JsonObject
from planning.errors import PlanningError

#: Young's modulus of cutter materials, N/mm^2: handbook values (HSS M2/M42 about 210-220 GPa;
#: cemented carbide WC-Co with 6-12 % Co about 580-630 GPa; TiCN cermet about 430 GPa).
YOUNGS_MODULUS_N_MM2 = {"hss": 210e3, "carbide": 600e3, "cermet": 430e3}
EFFECTIVE_DIAMETER_RATIO = 0.8  # fluted part's equivalent diameter / D (Kops & Vo 1990)
STABILITY_MARGIN = 0.8  # fraction of the lobes' depth a plan may use
IMMERSION_STEP = 0.125  # immersions rounded up to this for the lobes from modes (ae / D)

LIMIT_UNITS = {"force": "N", "deflection": "mm", "power": "kW", "torque": "N m",
               "chip": "mm", "stability": "mm"}  # fmt: skip


def second_moment_mm4(diameter_mm: float) -> float:
    """I = pi d^4 / 64 of a round section, mm^4."""
    return math.pi * diameter_mm**4 / 64.0


def cantilever_deflection_mm(
    force_n: ArrayLike, length_mm: float, e_n_mm2: float, i_mm4: float
) -> NDArray[np.float64]:
    """Tip deflection of a cantilever under a tip load, d = F L^3 / (3 E I), mm."""
    return np.asarray(force_n) * length_mm**3 / (3.0 * e_n_mm2 * i_mm4)


def cutting_speed_mm_s(diameter_mm: float, rpm: ArrayLike) -> NDArray[np.float64]:
    """Surface speed v = pi D n / 60, mm/s."""
    return math.pi * diameter_mm * np.asarray(rpm) / 60.0


def spindle_power_kw(
    tangential_n: ArrayLike, diameter_mm: float, rpm: ArrayLike
) -> NDArray[np.float64]:
    """Cutting power P = F_t v, kW (F_t: the mean tangential force summed over the teeth)."""
    return np.asarray(tangential_n) * cutting_speed_mm_s(diameter_mm, rpm) * 1e-6


def spindle_torque_nm(tangential_n: ArrayLike, diameter_mm: float) -> NDArray[np.float64]:
    """Spindle torque T = F_t D / 2, N m."""
    return np.asarray(tangential_n) * diameter_mm / 2.0 * 1e-3


def youngs_modulus_n_mm2(tool: EndMill, name: str = "") -> float:
    """The cutter's E: ``youngs_modulus_gpa``, else the handbook value of its material."""
    if tool.youngs_modulus_gpa is not None:
        return tool.youngs_modulus_gpa * 1e3
    e = YOUNGS_MODULUS_N_MM2.get(tool.material.strip().lower())
    if e is None:
        raise PlanningError(
            f"tool {name}: material = {tool.material!r} has no handbook E ("
            f"{', '.join(YOUNGS_MODULUS_N_MM2)}): give youngs_modulus_gpa (GPa)"
        )
    return e


def tool_stiffness_n_mm(tool: EndMill, name: str = "") -> float:
    """Static stiffness of the stick-out at its tip, 3 E I / L^3, N/mm."""
    i = second_moment_mm4(EFFECTIVE_DIAMETER_RATIO * tool.diameter_mm)
    return 3.0 * youngs_modulus_n_mm2(tool, name) * i / tool.length_mm**3


@dataclass(frozen=True)
class LobesTable:
    """Chatter-free depth by spindle speed (``cutlab analyze stability -o lobes.csv``)."""

    spindle_rpm: NDArray[np.float64]
    depth_limit_mm: NDArray[np.float64]  # inf where stable at every depth searched
    source: str = ""

    def depth_mm(self, rpm: NDArray[np.float64]) -> NDArray[np.float64]:
        """Interpolated in speed; outside the table's speeds: its nearest end (stated)."""
        return np.interp(rpm, self.spindle_rpm, self.depth_limit_mm)


def load_lobes(path: str | Path) -> LobesTable:
    """Read a lobes CSV: columns spindle_rpm, depth_limit_mm (empty = stable); one bad row is an
    error naming the file, line and value."""
    import pandas as pd

    p = Path(path)
    try:
        df = pd.read_csv(p, dtype=str, keep_default_na=False)  # the cells as written
    except (OSError, ValueError) as exc:
        raise PlanningError(f"{p}: cannot read the lobes table: {exc}") from None
    for col in ("spindle_rpm", "depth_limit_mm"):
        if col not in df.columns:
            raise PlanningError(
                f"{p}: no column {col!r} (expected spindle_rpm,depth_limit_mm[,chatter_hz])"
            )
    rpm = pd.to_numeric(df["spindle_rpm"], errors="coerce").to_numpy(float)
    raw = df["depth_limit_mm"]
    depth = pd.to_numeric(raw, errors="coerce").to_numpy(float)
    depth = np.where(raw.str.strip() == "", np.inf, depth)  # empty: stable at every depth
    for i in range(len(df)):
        if not (math.isfinite(rpm[i]) and rpm[i] > 0):
            raise PlanningError(
                f"{p}:{i + 2}: spindle_rpm = {df['spindle_rpm'].iloc[i]}: expected > 0 (rpm)"
            )
        if not depth[i] > 0:  # NaN (not a number) fails too
            raise PlanningError(
                f"{p}:{i + 2}: depth_limit_mm = {raw.iloc[i]}: expected > 0 (mm) or empty"
            )
    if len(rpm) < 1:
        raise PlanningError(f"{p}: the lobes table has no rows")
    order = np.argsort(rpm)
    if np.any(np.diff(rpm[order]) == 0):
        raise PlanningError(f"{p}: spindle_rpm repeats: one depth limit per speed")
    return LobesTable(rpm[order], depth[order], str(p))


@dataclass(frozen=True)
class Limits:
    """The limits of one tool on one machine; None: not limited.

    force_n: largest peak resultant force (an option, e.g. the fixture's); deflection_mm with
    stiffness_n_mm: the tool's static deflection limit; power_kw / torque_nm: the spindle's rated
    curve; chip_mm: largest chip thickness; lobes or (modes via ``tool``) the stability limit,
    times ``stability_margin``.
    """

    force_n: float | None = None
    deflection_mm: float | None = None
    stiffness_n_mm: float | None = None
    power_kw: float | None = None
    torque_nm: float | None = None
    chip_mm: float | None = None
    lobes: LobesTable | None = None
    stability_modes: bool = False
    stability_margin: float = STABILITY_MARGIN
    notes: tuple[str, ...] = field(default=())
    #: (limit, why) of each limit that could not be checked: a verdict with any is "unchecked"
    unchecked: tuple[tuple[str, str], ...] = field(default=())

    @property
    def has_stability(self) -> bool:
        return self.lobes is not None or self.stability_modes

    def to_json(self) -> JsonObject:
        lobes = None
        if self.lobes is not None:
            lobes = self.lobes.source
        elif self.stability_modes:
            lobes = "tool modes (analysis.stability, semi-discretization)"
        return {
            "force_n": self.force_n,
            "deflection_mm": self.deflection_mm,
            "tool_stiffness_n_mm": self.stiffness_n_mm,
            "power_kw": self.power_kw,
            "torque_nm": self.torque_nm,
            "base_rpm": self.base_rpm,
            "chip_mm": self.chip_mm,
            "stability": lobes,
            "stability_margin": self.stability_margin if lobes else None,
            "notes": list(self.notes),
            "unchecked": [{"limit": k, "reason": r} for k, r in self.unchecked],
        }

    @property
    def base_rpm(self) -> float | None:
        """Where the constant-torque region ends, rpm (P / T)."""
        if self.power_kw is None or self.torque_nm is None:
            return None
        return self.power_kw * 1e3 / self.torque_nm * 60.0 / (2 * math.pi)


def limits_for(
    tool: EndMill,
    machine: MachineConfig | None = None,
    *,
    tool_name: str = "",
    lobes: str | Path | LobesTable | None = None,
    force_limit_n: float | None = None,
    stability_margin: float = STABILITY_MARGIN,
) -> Limits:
    """The limits of ``tool`` on ``machine`` (either may lack some: then that limit is off)."""
    if not 0 < stability_margin <= 1:
        raise PlanningError(f"stability margin = {stability_margin}: expected 0 < margin <= 1")
    unchecked: list[tuple[str, str]] = []
    if machine is None:
        unchecked += [(k, "no machine") for k in ("power", "torque")]
    else:
        if machine.spindle_power_kw is None:
            unchecked.append(("power", f"machine {machine.name} gives no spindle_power_kw"))
        if machine.spindle_torque_nm is None:
            unchecked.append(("torque", f"machine {machine.name} gives no spindle_torque_nm"))
    table = load_lobes(lobes) if isinstance(lobes, (str, Path)) else lobes
    modes = table is None and bool(tool.modes)
    if table is None and not modes:
        unchecked.append(("stability", f"tool {tool_name} has no modes and no lobes table "
                          "(--lobes) was given"))  # fmt: skip
    if tool.deflection_tol_mm is None:
        unchecked.append(("deflection", f"tool {tool_name} gives no deflection_tol_mm"))
    if tool.max_chip_mm is None:
        unchecked.append(("chip", f"tool {tool_name} gives no max_chip_mm"))
    notes = [f"{k} not checked: {why}" for k, why in unchecked]
    return Limits(
        force_n=force_limit_n,
        deflection_mm=tool.deflection_tol_mm,
        stiffness_n_mm=tool_stiffness_n_mm(tool, tool_name),
        power_kw=machine.spindle_power_kw if machine else None,
        torque_nm=machine.spindle_torque_nm if machine else None,
        chip_mm=tool.max_chip_mm,
        lobes=table,
        stability_modes=modes,
        stability_margin=stability_margin,
        notes=tuple(notes),
        unchecked=tuple(unchecked),
    )


def modal_depth_limit_mm(
    tool: EndMill,
    coef: EndMillCoefficients,
    rpm: NDArray[np.float64],
    immersion: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Chatter-free depth from the tool's modes (analysis.stability, semi-discretization, down
    milling) at each (speed, radial immersion ae/D); immersions rounded up to IMMERSION_STEP,
    one case per distinct pair. inf where no lobe is found."""
    from analysis.stability import StabilityCase, stability_lobes

    rpm = np.asarray(rpm, float)
    imm = np.clip(np.ceil(np.asarray(immersion) / IMMERSION_STEP - 1e-9) * IMMERSION_STEP,
                  IMMERSION_STEP, 1.0)  # fmt: skip
    out = np.full(rpm.shape, np.inf)
    modes = tool.modes
    keys = np.round(np.stack([rpm, imm], -1), 6)
    uniq, inv = np.unique(keys, axis=0, return_inverse=True)
    for j, (n, a) in enumerate(uniq):
        case = StabilityCase(
            teeth=tool.flutes, milling="down", radial_immersion=float(a),
            kt_n_m2=coef.Ktc_n_mm2 * 1e6, kn_n_m2=coef.Krc_n_mm2 * 1e6,
            f_hz=np.array([m.f_hz for m in modes]), zeta=np.array([m.zeta for m in modes]),
            k_n_m=np.array([m.k_N_m for m in modes]), direction=tuple(m.axis for m in modes),
            rpm=np.array([float(n), float(n) * 1.0001]), name="tool modes",
        )  # fmt: skip
        out[inv.ravel() == j] = float(stability_lobes(case, "sd").depth_limit_mm[0])
    return out
