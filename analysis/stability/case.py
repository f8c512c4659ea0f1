"""A milling stability case from TOML: tool, cut, cutting coefficients, the tool's modes, spindle
speeds; validated, then held in SI units for the solvers.

::

    [tool]
    teeth = 2
    [cut]
    milling = "down"            # "up" or "down"
    radial_immersion = 0.05     # ae / D
    [coefficients]              # or coefficients_file = "forces.json" (`analyze forces --json`)
    Ktc_N_mm2 = 600.0
    Krc_N_mm2 = 200.0           # radial (normal) coefficient, absolute, not a ratio
    [[modes]]                   # or modes_file = "modes.toml" (`analyze modal --save/--json`)
    axis = "x"                  # x = feed, y = cross-feed (formerly `direction`, still read)
    f_hz = 922.0
    zeta = 0.011
    k_N_m = 1.34e6              # or m_kg
    [spindle]
    rpm_min = 5000
    rpm_max = 25000
    points = 200
    [search]                    # optional
    steps_per_period = 30       # semi-discretization steps per tooth period
    depth_max_mm = 20           # deepest cut searched (default 30 x the ZOA minimum)

The cutter turns clockwise seen from the spindle; the tooth angle phi is measured clockwise from
the y axis (Altintas; Insperger et al. 2003): up milling cuts from phi = 0 to arccos(1 - 2 ae/D),
down milling from arccos(2 ae/D - 1) to pi. Relative paths in the file are relative to it.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, TypeGuard

import numpy as np
from pydantic import Field, model_validator

from analysis.errors import ConfigError
from analysis.modal import renamed_mode_fields
from analysis.validation import Model, read_toml, validate

__all__ = ["StabilityCase", "load_case"]


class _Tool(Model):
    teeth: int = Field(ge=1, le=64, description="count of teeth, evenly spaced")


class _Cut(Model):
    milling: Literal["up", "down"] = Field(description='"up" or "down"')
    radial_immersion: float = Field(gt=0, le=1, description="ae/D, 0 < value <= 1")


class _Coefficients(Model):
    Ktc_N_mm2: float = Field(gt=0, le=20_000, description="N/mm^2, tangential")
    Krc_N_mm2: float = Field(ge=0, le=20_000, description="N/mm^2, radial (absolute)")


class _Mode(Model):
    """A mode in the one mode schema (the tool catalogue's)."""

    axis: Literal["x", "y"] = Field(description='"x" (feed) or "y" (cross-feed)')
    f_hz: float = Field(gt=0, le=100_000, description="Hz, natural frequency")
    zeta: float = Field(gt=0, lt=1, description="damping ratio, 0 < zeta < 1")
    k_N_m: float | None = Field(None, gt=0, description="N/m, modal stiffness")
    m_kg: float | None = Field(None, gt=0, description="kg, modal mass")

    @model_validator(mode="before")
    @classmethod
    def _renamed(cls, data: Any) -> Any:
        return renamed_mode_fields(data)

    @model_validator(mode="after")
    def _one_of(self) -> _Mode:
        if (self.k_N_m is None) == (self.m_kg is None):
            raise ValueError("give exactly one of k_N_m (N/m) or m_kg (kg)")
        return self


class _Spindle(Model):
    rpm_min: float = Field(gt=0, le=200_000, description="rpm")
    rpm_max: float = Field(gt=0, le=200_000, description="rpm")
    points: int = Field(200, ge=2, le=5000, description="count of speeds")

    @model_validator(mode="after")
    def _ordered(self) -> _Spindle:
        if not self.rpm_max > self.rpm_min:
            raise ValueError(f"rpm_max ({self.rpm_max}) must exceed rpm_min ({self.rpm_min})")
        return self


class _Search(Model):
    steps_per_period: int = Field(
        30, ge=4, le=400, description="semi-discretization steps per tooth period, 4..400"
    )
    depth_max_mm: float | None = Field(None, gt=0, le=1000, description="mm, deepest cut searched")


class _Config(Model):
    tool: _Tool
    cut: _Cut
    coefficients: _Coefficients | None = None
    coefficients_file: str | None = Field(None, description="`cutlab analyze forces --json` output")
    modes: tuple[_Mode, ...] = ()
    modes_file: str | None = Field(None, description="modes file (`cutlab analyze modal`)")
    spindle: _Spindle
    search: _Search = _Search()

    @model_validator(mode="after")
    def _sources(self) -> _Config:
        if (self.coefficients is None) == (self.coefficients_file is None):
            raise ValueError("give either [coefficients] or coefficients_file, not both or none")
        if bool(self.modes) == (self.modes_file is not None):
            raise ValueError("give either [[modes]] tables or modes_file, not both or none")
        return self


@dataclass(frozen=True)
class StabilityCase:
    """A validated case in SI units: ``kt_n_m2``/``kn_n_m2`` cutting coefficients, modes as arrays
    (``f_hz``, ``zeta``, ``k_n_m``, ``direction`` 'x'/'y'), the speed grid ``rpm``."""

    teeth: int
    milling: str
    radial_immersion: float
    kt_n_m2: float
    kn_n_m2: float
    f_hz: np.ndarray
    zeta: np.ndarray
    k_n_m: np.ndarray
    direction: tuple[str, ...]
    rpm: np.ndarray
    steps_per_period: int = 30
    depth_max_mm: float | None = None
    name: str = ""

    @property
    def directions(self) -> tuple[str, ...]:
        """The flexible directions, in x, y order (a direction without modes is rigid)."""
        return tuple(d for d in "xy" if d in self.direction)

    @property
    def cut_angles_rad(self) -> tuple[float, float]:
        """Entry and exit angle of a tooth, rad."""
        a = self.radial_immersion
        if self.milling == "up":
            return 0.0, math.acos(1 - 2 * a)
        return math.acos(2 * a - 1), math.pi

    def tooth_h(self, phi: np.ndarray) -> np.ndarray:
        """Directional factor of one tooth in cut at angle ``phi`` (rad): (..., 2, 2), N/m^2;
        the force on the tool is F = -w sum_j H(phi_j) (q(t) - q(t - tau)) (Insperger et al.
        2003, eq 4), q = (x, y) the tool's displacement, w the axial depth."""
        s, c = np.sin(phi), np.cos(phi)
        kt, kn = self.kt_n_m2, self.kn_n_m2
        t, n = kt * c + kn * s, -kt * s + kn * c  # -F_x and -F_y per unit chip and depth
        return np.stack([np.stack([t * s, t * c], -1), np.stack([n * s, n * c], -1)], -2)

    def mean_h(self) -> np.ndarray:
        """The directional factor averaged over a tooth period (the ZOA's), 2 x 2, N/m^2:
        (N / 2 pi) times the integral of H over the cut, in closed form."""
        a, b = self.cut_angles_rad

        def prim(p: float) -> np.ndarray:  # antiderivatives of s c, s^2, c^2
            return np.array([math.sin(p) ** 2 / 2, p / 2 - math.sin(2 * p) / 4,
                             p / 2 + math.sin(2 * p) / 4])  # fmt: skip

        sc, ss, cc = prim(b) - prim(a)
        kt, kn = self.kt_n_m2, self.kn_n_m2
        h = np.array(
            [[kt * sc + kn * ss, kt * cc + kn * sc], [-kt * ss + kn * sc, -kt * sc + kn * cc]]
        )
        return self.teeth / (2 * math.pi) * h

    def receptance(self, freq_hz: np.ndarray) -> np.ndarray:
        """Tool-point receptance per flexible direction, (..., n_dir) complex, m/N."""
        f = np.asarray(freq_hz, float)[..., None]
        r = f / self.f_hz
        g = 1.0 / (self.k_n_m * (1 - r * r + 2j * self.zeta * r))
        return np.stack([g[..., self._in(d)].sum(-1) for d in self.directions], -1)

    def _in(self, d: str) -> np.ndarray:
        return np.array([x == d for x in self.direction])

    def position_matrix(self) -> np.ndarray:
        """C, n_dir x n_modes: a direction's displacement is the sum of its modal coordinates."""
        return np.array([self._in(d) for d in self.directions], float)


# ---------------------------------------------------------------------------------- loading


def load_case(path: str | Path) -> StabilityCase:
    """Read and validate a stability case (see the module's docstring)."""
    p = Path(path)
    data, text = read_toml(p)
    cfg = validate(_Config, data, str(p), text)
    if cfg.coefficients is not None:
        kt, kn = cfg.coefficients.Ktc_N_mm2, cfg.coefficients.Krc_N_mm2
    else:
        kt, kn = _coefficients_file(p, cfg.coefficients_file or "")
    modes: list[tuple[str, float, float, float]]
    if cfg.modes:
        modes = [(m.axis, m.f_hz, m.zeta, _stiffness(m)) for m in cfg.modes]
    else:
        modes = _modes_file(p, cfg.modes_file or "")
    d, f, z, k = zip(*modes)
    s = cfg.spindle
    return StabilityCase(
        teeth=cfg.tool.teeth, milling=cfg.cut.milling, radial_immersion=cfg.cut.radial_immersion,
        kt_n_m2=kt * 1e6, kn_n_m2=kn * 1e6, f_hz=np.array(f), zeta=np.array(z), k_n_m=np.array(k),
        direction=tuple(d), rpm=np.linspace(s.rpm_min, s.rpm_max, s.points),
        steps_per_period=cfg.search.steps_per_period, depth_max_mm=cfg.search.depth_max_mm,
        name=p.stem,
    )  # fmt: skip


def _stiffness(m: _Mode) -> float:
    if m.k_N_m is not None:
        return m.k_N_m
    assert m.m_kg is not None  # _Mode._one_of: exactly one of k_N_m and m_kg
    return m.m_kg * (2 * math.pi * m.f_hz) ** 2


def _side_file(cfg_path: Path, name: str, key: str) -> tuple[Path, Any]:
    """A file named in the config (relative to it) as JSON, or TOML for a .toml name."""
    p = Path(name)
    p = p if p.is_absolute() else cfg_path.parent / p
    if p.suffix.lower() == ".toml":
        return p, read_toml(p)[0]
    try:
        return p, json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"{cfg_path}: {key} = {name!r}: file {p} not found") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ConfigError(f"{cfg_path}: {key} = {name!r}: not a JSON file: {exc}") from None


def _coefficients_file(cfg_path: Path, name: str) -> tuple[float, float]:
    """Ktc, Krc (N/mm^2) from `cutlab analyze forces --json` output (the end-mill fit)."""
    p, data = _side_file(cfg_path, name, "coefficients_file")
    coef = data.get("coefficients") if isinstance(data, dict) else None
    if not isinstance(coef, dict) or data.get("model", "endmill") != "endmill":
        raise ConfigError(
            f"{p}: coefficients_file: expected the JSON of `cutlab analyze forces --model endmill "
            "--json` (coefficients.Ktc and Krc, N/mm^2)"
        )
    if data.get("success") is False:
        raise ConfigError(f"{p}: coefficients_file: the fit failed ({data.get('message', '')})")
    out = []
    for key, lo in (("Ktc", 0.0), ("Krc", -1.0)):
        v = coef.get(key)
        if not isinstance(v, int | float) or isinstance(v, bool) or not lo < v <= 20_000:
            raise ConfigError(
                f"{p}: coefficients.{key} = {v!r}: expected a number, "
                f"{'0 <' if lo == 0 else '0 <='} value <= 20000 (N/mm^2)"
            )
        out.append(float(v))
    return out[0], out[1]


def _modes_file(cfg_path: Path, name: str) -> list[tuple[str, float, float, float]]:
    """(direction, f_hz, zeta, k_n_m) of the x and y modes of a modes file: the cutlab-modes
    file of `cutlab analyze modal --save` (TOML or JSON), or `analyze modal --json` output whose
    modes carry a modal stiffness (``stiffness_n_m`` or ``mass_kg``)."""
    p, data = _side_file(cfg_path, name, "modes_file")
    if isinstance(data, dict) and data.get("format") == "cutlab-modes":
        from analysis.modal import load_modes  # the saved file's own loader and validation

        ms = load_modes(p)
        rows: list[tuple[object, ...]]
        rows = [(d, m.f_hz, m.zeta, m.k_N_m, m.m_kg)
                for d, modes in ms.directions.items() for m in modes]  # fmt: skip
    elif isinstance(data, dict) and isinstance(data.get("modes"), list):
        rows = []
        for i, m in enumerate(data["modes"]):
            if not isinstance(m, dict):
                raise ConfigError(f"{p}: modes[{i}] = {m!r}: expected a table")
            keys = ("frequency_hz", "damping_ratio", "stiffness_n_m", "mass_kg")
            rows.append((m.get("axis", m.get("channel")), *(m.get(k) for k in keys)))
    else:
        raise ConfigError(
            f"{p}: modes_file: expected a cutlab-modes file (`cutlab analyze modal --save`) or "
            "the JSON of `cutlab analyze modal --json`"
        )
    out: list[tuple[str, float, float, float]] = []
    for i, (d, f, z, k, m) in enumerate(rows):
        if not isinstance(d, str) or d not in ("x", "y"):
            continue  # z and other channels do not enter a 2-D milling model
        where = f"{p}: mode {i} (direction {d})"
        f_hz = _within(where, "frequency_hz", f, 0, 100_000, "Hz")
        zeta = _within(where, "damping_ratio", z, 0, 1, "fraction")
        if _number(k) and k > 0:
            stiff = float(k)
        elif _number(m) and m > 0:
            stiff = float(m) * (2 * math.pi * f_hz) ** 2
        else:
            raise ConfigError(
                f"{where}: stiffness_n_m = {k!r}: no modal stiffness (N/m) or mass_kg; a force/"
                "force test gives none: tap the tool with a displacement or acceleration sensor"
            )
        out.append((d, f_hz, zeta, stiff))
    if not out:
        raise ConfigError(f"{p}: modes_file: no modes in direction x or y")
    return out


def _within(where: str, key: str, v: object, lo: float, hi: float, unit: str) -> float:
    """``v`` as a float if it is a number with lo < v < hi, else one clear error line."""
    if not _number(v) or not lo < v < hi:
        raise ConfigError(f"{where}: {key} = {v!r}: expected {lo} < value < {hi} ({unit})")
    return float(v)


def _number(v: object) -> TypeGuard[float]:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
