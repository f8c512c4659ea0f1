"""Volts <-> newtons for a piezo dynamometer behind charge amplifiers.

The chain per channel (Kistler dynamometer + 5070/5080-style charge amplifier)::

    true force F (cutlab axes, N)
      -> dynamometer axes:        F_dyn  = sign * F                   (sign = +-1 per channel)
      -> cross-talk (cal. sheet):  F_meas = C @ F_dyn                  (measured = C @ true)
      -> charge:                   q      = S * F_meas                 (S sensitivity, pC/N)
      -> amplifier output:         V      = q / (S_amp * R) + V0 + d*(t - t_zero)

``S_amp`` is the sensitivity dialled into the amplifier (normally the sheet's ``S``, so the charge
cancels and V = F_meas / R), ``R`` the amplifier's scale in N/V (mechanical units per volt), ``V0``
the output at zero load after reset/operate and ``d`` the amplifier's linear drift (V/s). The
inverse, applied to recorded volts, is the affine map ``force = M @ (V - V0 - d (t - t_zero))`` with
``M = diag(sign) @ inv(C) @ diag(R * S_amp / S)``; ``rig.log.writer`` stores M, V0, t_zero and d in
the run file (``analysis.runs.file`` documents where) and the raw volts are kept beside it.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace
from typing import TypedDict

import numpy as np

from analysis.config import Dynamometer, RigConfig
from analysis.errors import ConfigError
from analysis.runs import file as rf
from rig.errors import RigError


class CalibrationError(RigError, ValueError):
    """A calibration has the wrong shape, a singular cross-talk matrix or unusable zero data."""


#: zero_v's and drift_v_s's default: none given, zeros (__post_init__ makes them (c,) arrays)
_NONE_GIVEN = np.zeros(0)


def _or_zero(v: object) -> object:
    """0.0 for a zero or drift not given (the default, or None as a caller may pass)."""
    return 0.0 if v is None or v is _NONE_GIVEN else v


def _vec(name: str, v: object, n: int) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64)
    if a.ndim == 0:
        a = np.full(n, float(a))
    if a.shape != (n,):
        raise CalibrationError(f"{name} has shape {a.shape}: expected ({n},), one per channel")
    if not np.all(np.isfinite(a)):
        raise CalibrationError(f"{name} = {a.tolist()}: every value must be finite")
    return a


@dataclass(frozen=True)
class Calibration:
    """Calibration of a dynamometer + amplifier chain; arrays have one entry per channel.

    sensitivity_pc_n : (c,) pC/N, from the dynamometer's calibration sheet (non-zero).
    range_n_v : (c,) N/V, amplifier scale (> 0).
    sign : (c,) +-1, dynamometer axis to cutlab axis.
    crosstalk : (c, c), measured = crosstalk @ true (identity when the sheet gives none).
    amp_sensitivity_pc_n : (c,) pC/N set on the amplifier (default: ``sensitivity_pc_n``).
    zero_v : (c,) V at zero load; zero_time_s : s on the run clock (NaN: never zeroed).
    drift_v_s : (c,) V/s linear amplifier drift removed relative to ``zero_time_s``.
    """

    channel_names: tuple[str, ...]
    sensitivity_pc_n: np.ndarray
    range_n_v: np.ndarray
    sign: np.ndarray
    crosstalk: np.ndarray
    amp_sensitivity_pc_n: np.ndarray
    calibration_id: str = ""
    dynamometer: str = ""
    zero_v: np.ndarray = field(default_factory=lambda: _NONE_GIVEN)
    zero_time_s: float = math.nan
    drift_v_s: np.ndarray = field(default_factory=lambda: _NONE_GIVEN)

    def __post_init__(self) -> None:
        n = len(self.channel_names)
        if n == 0:
            raise CalibrationError("a calibration needs at least one channel")
        s = object.__setattr__
        s(self, "sensitivity_pc_n", _vec("sensitivity_pc_n", self.sensitivity_pc_n, n))
        s(self, "range_n_v", _vec("range_n_v", self.range_n_v, n))
        s(self, "sign", _vec("sign", self.sign, n))
        s(self, "amp_sensitivity_pc_n", _vec("amp_sensitivity_pc_n", self.amp_sensitivity_pc_n, n))
        s(self, "zero_v", _vec("zero_v", _or_zero(self.zero_v), n))
        s(self, "drift_v_s", _vec("drift_v_s", _or_zero(self.drift_v_s), n))
        if np.any(self.sensitivity_pc_n == 0) or np.any(self.amp_sensitivity_pc_n == 0):
            raise CalibrationError("sensitivity_pc_n must be non-zero on every channel (pC/N)")
        if np.any(self.range_n_v <= 0):
            raise CalibrationError(f"range_n_v = {self.range_n_v.tolist()}: must be > 0 (N/V)")
        if not np.all(np.isin(self.sign, (-1.0, 1.0))):
            raise CalibrationError(f"sign = {self.sign.tolist()}: each must be +1 or -1")
        c = np.asarray(self.crosstalk, dtype=np.float64)
        if c.shape != (n, n):
            raise CalibrationError(
                f"crosstalk matrix is {'x'.join(map(str, c.shape)) or 'scalar'}: expected "
                f"{n}x{n} for {n} channels ({', '.join(self.channel_names)})"
            )
        if not np.all(np.isfinite(c)) or np.linalg.cond(c) > 1e8:
            raise CalibrationError(
                f"crosstalk matrix {c.tolist()} is singular or not finite: cannot invert it"
            )
        s(self, "crosstalk", c)

    # -- construction ------------------------------------------------------------------------

    @classmethod
    def from_dynamometer(
        cls, dyno: Dynamometer, n_daq_channels: int | None = None, where: str = "rig config"
    ) -> Calibration:
        """The calibration of a configured dynamometer; checks it matches the DAQ's channels."""
        n = len(dyno.channels)
        if n_daq_channels is not None and n_daq_channels != n:
            raise ConfigError(
                f"{where}: dynamometer.channels has {n} channels "
                f"({', '.join(c.name for c in dyno.channels)}) but daq.channels has "
                f"{n_daq_channels}: the calibration must have one entry per DAQ channel"
            )
        sens = np.array([c.sensitivity_pc_n for c in dyno.channels], dtype=np.float64)
        return cls(
            channel_names=tuple(c.name for c in dyno.channels),
            sensitivity_pc_n=sens,
            range_n_v=np.array([c.range_n_v for c in dyno.channels], dtype=np.float64),
            sign=np.array([c.sign for c in dyno.channels], dtype=np.float64),
            crosstalk=np.eye(n) if dyno.crosstalk is None else np.asarray(dyno.crosstalk),
            amp_sensitivity_pc_n=sens.copy(),  # its own array, as two lists gave
            calibration_id=dyno.calibration_id,
            dynamometer=dyno.model,
        )

    @classmethod
    def from_rig(cls, rig: RigConfig, where: str = "rig config") -> Calibration:
        return cls.from_dynamometer(rig.dynamometer, len(rig.daq.channels), where)

    @property
    def n_channels(self) -> int:
        return len(self.channel_names)

    # -- forward: force -> charge -> volts (simulation, round-trip checks) --------------------

    def charge_pc(self, force_n: np.ndarray) -> np.ndarray:
        """Charge (pC) of each channel for true forces ``force_n`` (n, c) in cutlab axes."""
        f = np.asarray(force_n, dtype=np.float64)
        measured = (f * self.sign) @ self.crosstalk.T
        return measured * self.sensitivity_pc_n

    def volts_from_charge(self, charge_pc: np.ndarray) -> np.ndarray:
        """Amplifier output (V) for charge (n, c) pC, before zero offset and drift."""
        return np.asarray(charge_pc, dtype=np.float64) / (
            self.amp_sensitivity_pc_n * self.range_n_v
        )

    def volts_from_force(self, force_n: np.ndarray, time_s: np.ndarray | None = None) -> np.ndarray:
        """Amplifier output (n, c) V for true forces (n, c) N, including zero offset and drift."""
        v = self.volts_from_charge(self.charge_pc(force_n)) + self.zero_v
        if time_s is not None and np.any(self.drift_v_s):
            v = v + self._dt(time_s)[:, None] * self.drift_v_s
        return v

    # -- inverse: volts -> newtons -------------------------------------------------------------

    @functools.cached_property
    def volts_to_n(self) -> np.ndarray:
        """(c, c) N/V: force = volts_to_n @ (corrected volts). Cached: the fields are frozen."""
        gain = self.range_n_v * self.amp_sensitivity_pc_n / self.sensitivity_pc_n
        m = (self.sign[:, None] * np.linalg.inv(self.crosstalk)) * gain[None, :]
        m.flags.writeable = False  # shared by every call
        return m

    def _dt(self, time_s: np.ndarray) -> np.ndarray:
        t0 = self.zero_time_s if math.isfinite(self.zero_time_s) else 0.0
        return np.asarray(time_s, dtype=np.float64) - t0

    def force_from_volts(self, volts: np.ndarray, time_s: np.ndarray | None = None) -> np.ndarray:
        """Forces (n, c) N in cutlab axes from amplifier volts (n, c), zero and drift removed.

        ``time_s`` (n,) on the run clock is needed only when a drift is set.
        """
        v = np.asarray(volts, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != self.n_channels:
            raise CalibrationError(
                f"volts has shape {v.shape}: expected (n, {self.n_channels}) for channels "
                f"{', '.join(self.channel_names)}"
            )
        if np.any(self.drift_v_s) and time_s is None:
            raise CalibrationError("a drift is set: force_from_volts needs time_s (s)")
        t_s = np.zeros(0) if time_s is None else time_s  # read with a drift only (checked)
        return rf.volts_to_force(
            v, t_s, self.volts_to_n, self.zero_v, self.zero_time_s, self.drift_v_s
        )

    # -- zeroing and drift -------------------------------------------------------------------

    def zeroed(self, volts_at_rest: np.ndarray, time_s: float) -> Calibration:
        """A copy zeroed on samples taken with no load (n, c) V at run-clock time ``time_s``.

        Drift is reset: a new zero starts a new drift line (reset/operate before each cut).
        """
        v = np.asarray(volts_at_rest, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != self.n_channels or len(v) == 0:
            raise CalibrationError(
                f"zero samples have shape {v.shape}: expected (n >= 1, {self.n_channels})"
            )
        return replace(
            self, zero_v=v.mean(axis=0), zero_time_s=float(time_s), drift_v_s=_NONE_GIVEN
        )

    def with_drift(self, drift_v_s: np.ndarray) -> Calibration:
        return replace(self, drift_v_s=drift_v_s)

    def as_attrs(self) -> CalibrationAttrs:
        """The sheet values as HDF5 attributes (see analysis.runs.file, /calibration)."""
        return {
            "calibration_id": self.calibration_id,
            "dynamometer": self.dynamometer,
            "channel_names": list(self.channel_names),
            "sensitivity_pc_n": self.sensitivity_pc_n,
            "amp_sensitivity_pc_n": self.amp_sensitivity_pc_n,
            "range_n_v": self.range_n_v,
            "sign": self.sign,
            "crosstalk": self.crosstalk,
        }


class CalibrationAttrs(TypedDict):
    """A calibration sheet as the run file's ``/calibration`` attributes (per channel: pC/N,
    N/V, sign; the cross-talk matrix)."""

    calibration_id: str
    dynamometer: str
    channel_names: list[str]
    sensitivity_pc_n: np.ndarray
    amp_sensitivity_pc_n: np.ndarray
    range_n_v: np.ndarray
    sign: np.ndarray
    crosstalk: np.ndarray


@dataclass(frozen=True)
class DriftFit:
    """A linear drift fitted on unloaded samples: volts = zero_v + drift_v_s * (t - t_ref_s)."""

    zero_v: np.ndarray  # (c,) V at t_ref_s
    drift_v_s: np.ndarray  # (c,) V/s
    t_ref_s: float
    residual_rms_v: np.ndarray  # (c,) V
    n_samples: int


def fit_drift(
    time_s: np.ndarray, volts: np.ndarray, at_rest: np.ndarray, t_ref_s: float | None = None
) -> DriftFit:
    """Least-squares line through the unloaded samples of a run, per channel.

    time_s : (n,) s; volts : (n, c) V; at_rest : (n,) bool, True where the tool is out of the cut
    (before and after the cut at least: the line needs two separated stretches to see drift).
    """
    t = np.asarray(time_s, dtype=np.float64)
    v = np.asarray(volts, dtype=np.float64)
    m = np.asarray(at_rest, dtype=bool)
    if v.ndim != 2 or t.shape != (len(v),) or m.shape != t.shape:
        raise CalibrationError(
            f"fit_drift: time_s {t.shape}, volts {v.shape}, at_rest {m.shape}: "
            "expected (n,), (n, c), (n,)"
        )
    tr, vr = t[m], v[m]
    if len(tr) < 2 or np.ptp(tr) <= 0:
        raise CalibrationError(
            f"fit_drift: {len(tr)} samples at rest spanning {np.ptp(tr) if len(tr) else 0} s: "
            "need rest before and after the cut"
        )
    t_ref = float(tr[0]) if t_ref_s is None else float(t_ref_s)
    a = np.column_stack([np.ones_like(tr), tr - t_ref])
    coef, *_ = np.linalg.lstsq(a, vr, rcond=None)
    resid = vr - a @ coef
    return DriftFit(
        zero_v=coef[0],
        drift_v_s=coef[1],
        t_ref_s=t_ref,
        residual_rms_v=np.sqrt(np.mean(resid**2, axis=0)),
        n_samples=int(len(tr)),
    )


def compensate(cal: Calibration, fit: DriftFit) -> Calibration:
    """``cal`` with the zero and drift of a :class:`DriftFit` (sheet values unchanged)."""
    return replace(cal, zero_v=fit.zero_v, zero_time_s=fit.t_ref_s, drift_v_s=fit.drift_v_s)
