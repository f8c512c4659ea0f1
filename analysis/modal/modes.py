"""A tap test's modes in a file, for a later stability calculation (`analyze modal --save`).

The file is TOML (or JSON with the same keys, for a path ending in ``.json``)::

    format = "cutlab-modes"
    version = 1
    source = "tap_x.csv"          # the hammer record the modes came from (free text)

    [[modes.x]]                   # one table per mode of direction x, ascending in frequency
    f_hz = 1810.0                 # undamped natural frequency, Hz
    zeta = 0.03                   # damping ratio, fraction of critical, 0 < zeta < 1
    k_N_m = 2.0e7                 # modal stiffness k_r = m_r w_r^2, N/m (0 < k <= 1e9)
    m_kg = 0.1546                 # modal mass m_r = 1 / R_r, kg

The field names are the one mode schema of the tool catalogue (``[[tools.NAME.modes]]``); files
with the former names (``frequency_hz``, ``damping_ratio``, ``stiffness_n_m``, ``mass_kg``) are
still read, with a deprecation note.

Each direction (``x``, ``y`` ... a response channel's name) is read as a driving-point FRF
H(w) = sum_r 1 / (k_r (1 - (w / w_r)^2 + 2 i zeta_r w / w_r)) (:meth:`ModeSet.receptance`).
``k_N_m`` and ``m_kg`` come together or not at all (a force/force dynamometer FRF gives
neither), and must agree with the frequency (k = m (2 pi f)^2 within 1 %).
``load_modes(path) -> ModeSet`` validates; a bad value is refused as ``file:line: field = value:
why (unit)``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import tomli_w
from numpy.typing import ArrayLike
from pydantic import Field, model_validator

from analysis.config import FormerModeNames, renamed_mode_fields
from analysis.errors import AnalysisError, ConfigError
from analysis.validation import Model, read_toml, validate

if TYPE_CHECKING:
    from analysis.modal.hammer import ModeEstimate

__all__ = ["ModalMode", "ModeSet", "load_modes", "renamed_mode_fields", "save_modes"]

FORMAT = "cutlab-modes"
#: Stiffer modes are not saved: they do not limit a cut (and config numbers stop at 1e9).
MAX_STIFFNESS_N_M = 1e9


@dataclass(frozen=True)
class ModalMode(FormerModeNames):
    """One mode of a direction: natural frequency (Hz), damping ratio, modal stiffness (N/m) and
    mass (kg), these two None where the response was a force."""

    f_hz: float
    zeta: float
    k_N_m: float | None = None
    m_kg: float | None = None

    @property
    def damping_n_s_m(self) -> float | None:
        """Modal viscous damping c = 2 zeta sqrt(k m), N s/m."""
        if self.k_N_m is None or self.m_kg is None:
            return None
        return 2 * self.zeta * math.sqrt(self.k_N_m * self.m_kg)

    # Former attribute names (FormerModeNames gives frequency_hz, damping_ratio).

    @property
    def stiffness_n_m(self) -> float | None:
        return self.k_N_m

    @property
    def mass_kg(self) -> float | None:
        return self.m_kg


@dataclass(frozen=True)
class ModeSet:
    """Modes per direction (``directions``: name -> modes ascending in frequency) and the
    ``source`` record."""

    directions: dict[str, tuple[ModalMode, ...]]
    source: str = ""

    def modes(self, direction: str) -> tuple[ModalMode, ...]:
        if direction not in self.directions:
            raise AnalysisError(
                f"no modes for direction {direction!r}: the file has {sorted(self.directions)}"
            )
        return self.directions[direction]

    def receptance(self, direction: str, freq_hz: ArrayLike) -> np.ndarray:
        """Driving-point receptance (m/N) of ``direction`` at ``freq_hz``: the sum of its modes."""
        f = np.asarray(freq_hz, float)
        h = np.zeros(f.shape, complex)
        for m in self.modes(direction):
            if m.k_N_m is None:
                raise AnalysisError(
                    f"direction {direction!r}, mode at {m.f_hz:g} Hz: no modal stiffness "
                    "(the tap test's response was a force); a receptance needs a displacement or "
                    "acceleration response"
                )
            r = f / m.f_hz
            h += 1.0 / (m.k_N_m * (1 - r * r + 2j * m.zeta * r))
        return h


class _Mode(Model):
    f_hz: float = Field(gt=0, le=200_000, description="Hz")
    zeta: float = Field(gt=0, lt=1, description="damping ratio, fraction of critical")
    k_N_m: float | None = Field(
        None, gt=0, le=MAX_STIFFNESS_N_M, description="N/m, modal stiffness"
    )
    m_kg: float | None = Field(None, gt=0, description="kg, modal mass")

    @model_validator(mode="before")
    @classmethod
    def _renamed(cls, data: Any) -> Any:
        return renamed_mode_fields(data)

    @model_validator(mode="after")
    def _consistent(self) -> _Mode:
        k, m = self.k_N_m, self.m_kg
        if (k is None) != (m is None):
            raise ValueError("k_N_m and m_kg come together or not at all")
        if k is not None and m is not None:
            km = m * (2 * math.pi * self.f_hz) ** 2
            if abs(k - km) > 0.01 * k:
                raise ValueError(
                    f"k_N_m = {k:g} disagrees with m_kg (2 pi f_hz)^2 = "
                    f"{km:g} by more than 1 % (N/m)"
                )
        return self


class _ModesFile(Model):
    format: Literal["cutlab-modes"] = Field(description=f'"{FORMAT}"')
    version: Literal[1] = Field(description="1")
    source: str = ""
    modes: dict[str, list[_Mode]] = Field(min_length=1, description="direction -> modes")

    @model_validator(mode="after")
    def _nonempty(self) -> _ModesFile:
        for d, ms in self.modes.items():
            if not ms:
                raise ValueError(f"modes.{d}: no modes (leave the direction out)")
        return self


def load_modes(path: str | Path) -> ModeSet:
    """Read and validate a modes file written by :func:`save_modes` (or by hand)."""
    p = Path(path)
    if p.suffix.lower() == ".json":
        try:
            text = p.read_text(encoding="utf-8")
            data = json.loads(text)
        except FileNotFoundError:
            raise ConfigError(f"{p}: modes file not found") from None
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ConfigError(f"{p}: not a JSON modes file: {exc}") from None
        text = ""  # no line numbers for JSON
    else:
        data, text = read_toml(p)
    if not isinstance(data, dict):
        raise ConfigError(f"{p}: expected a table of format, version, source, modes")
    f = validate(_ModesFile, data, str(p), text)
    dirs = {
        d: tuple(sorted((ModalMode(**m.model_dump()) for m in ms), key=lambda m: m.f_hz))
        for d, ms in f.modes.items()
    }
    return ModeSet(dirs, f.source)


def save_modes(
    path: str | Path, modes: Sequence[ModeEstimate], source: str = "", merge: bool = True,
) -> tuple[Path, list[str]]:  # fmt: skip
    """Write ``modes`` (``ModeEstimate``-like: ``channel``, ``frequency_hz``, ``damping_ratio``,
    ``stiffness_n_m``, ``mass_kg``; NaN stiffness = none) as a modes file in the one mode schema
    (.toml, or .json). With ``merge``, the directions of an existing modes file at ``path`` that
    ``modes`` do not have are kept (a tap in x, then one in y, into one file). Returns the path
    and notes: directions kept, modes left out (stiffer than 1e9 N/m: they do not limit a cut)."""
    p = Path(path)
    dirs: dict[str, list[dict[str, float]]] = {}
    notes = []
    for m in sorted(modes, key=lambda m: (m.channel, m.frequency_hz)):
        row = {"f_hz": float(m.frequency_hz), "zeta": float(m.damping_ratio)}
        k, mass = m.stiffness_n_m, m.mass_kg
        if k is not None and math.isfinite(k):
            if k > MAX_STIFFNESS_N_M:
                notes.append(f"{m.channel}: mode at {m.frequency_hz:.0f} Hz, stiffness "
                                f"{k:.3g} N/m > {MAX_STIFFNESS_N_M:g} N/m: not saved")  # fmt: skip
                continue
            row.update(k_N_m=float(k), m_kg=float(mass))
        dirs.setdefault(m.channel, []).append(row)
    if not dirs:
        raise AnalysisError(f"{p}: no modes to save")
    if merge and p.exists():
        old = load_modes(p)
        kept = {d: ms for d, ms in old.directions.items() if d not in dirs}
        for d, ms in kept.items():
            dirs[d] = [{k: v for k, v in vars(m).items() if v is not None} for m in ms]
        if kept:
            source = "; ".join(x for x in (old.source, source) if x)
            notes.append(f"{p}: kept direction(s) {', '.join(sorted(kept))} of the earlier file")
        dirs = dict(sorted(dirs.items()))
    data = {"format": FORMAT, "version": 1, "source": source, "modes": dirs}
    validate(_ModesFile, data, str(p))  # what is written must load
    if p.suffix.lower() == ".json":
        text = json.dumps(data, indent=2) + "\n"
    else:
        head = ("# Tap-test modes (cutlab analyze modal --save); read by "
                "analysis.modal.load_modes.\n# Per direction: f_hz (Hz), zeta (damping ratio), "
                "k_N_m (N/m), m_kg (kg).\n")  # fmt: skip
        text = head + tomli_w.dumps(data)
    try:
        p.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise AnalysisError(f"{p}: cannot write the modes file: {exc}") from None
    return p, notes
