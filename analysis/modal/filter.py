"""The dynamometer's structural modes as a filter: true force in -> measured force out.

Each axis is one mode (seed 003 Table 2) with unit static gain::

    G(s) = w_n^2 / (s^2 + 2 zeta w_n s + w_n^2)

discretised at the sample rate with a zero-order hold (``scipy.signal.cont2discrete``), which
keeps the poles exactly (z = exp(s T)): an impulse response of the filter has the continuous
natural frequency and damping, so modal identification on it can be checked against the table.
Cross-talk (``Dynamometer.crosstalk``, measured = C @ true) is applied after the modes.

Used three ways:

- ``DynamometerFilter.apply(force)`` filters a whole record (synthetic runs, tests);
- ``DynamometerFilter.stream()`` returns a stateful ``FilterState`` whose ``process(block)``
  filters consecutive blocks exactly as one long record would be (the simulated rig);
- ``DynamometerFilter.periodic_response(waveform)`` gives the steady-state response to a periodic
  force sampled over one period (the identification fits through it, so the modes do not bias the
  coefficients).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal

from analysis.config import Dynamometer, Mode
from analysis.errors import AnalysisError

#: a discrete filter's numerator and denominator
_BA = tuple[NDArray[np.float64], NDArray[np.float64]]

AXES: tuple[Literal["x"], Literal["y"], Literal["z"]] = ("x", "y", "z")

__all__ = ["AXES", "DynamometerFilter", "FilterState"]


@dataclass(frozen=True)
class DynamometerFilter:
    """Per-axis second-order modes at a sample rate.

    ``modes``: one :class:`analysis.config.Mode` per axis that has one (axes without a mode pass
    unchanged); ``rate_hz`` the sample rate; ``crosstalk`` an optional (3, 3) matrix.
    """

    modes: tuple[Mode, ...]
    rate_hz: float
    crosstalk: np.ndarray | None = None
    _ba: tuple[_BA | None, ...] = field(init=False, repr=False, compare=False)
    # Harmonic responses by (harmonics, period): a fit's phase search filters one run's
    # regressors some 35 times at the same period, and freqz was half of that work.
    _harmonics: dict[tuple[int, float], NDArray[np.complex128]] = field(
        init=False, repr=False, compare=False, default_factory=dict
    )

    def __post_init__(self) -> None:
        if not self.rate_hz > 0:
            raise AnalysisError(f"rate_hz = {self.rate_hz}: must be > 0 (Hz)")
        ba: list[_BA | None] = [None, None, None]
        for m in self.modes:
            if m.f_hz >= self.rate_hz / 2:
                raise AnalysisError(
                    f"mode {m.axis} at {m.f_hz} Hz is above the Nyquist frequency "
                    f"({self.rate_hz / 2} Hz) of rate_hz = {self.rate_hz}: sample faster"
                )
            wn = 2 * np.pi * m.f_hz
            num, den = [wn**2], [1.0, 2 * m.zeta * wn, wn**2]
            tf = (np.array(num), np.array(den))
            bd, ad, _ = signal.cont2discrete(tf, 1.0 / self.rate_hz, method="zoh")
            ba[AXES.index(m.axis)] = (np.ravel(bd), np.ravel(ad))
        object.__setattr__(self, "_ba", tuple(ba))
        if self.crosstalk is not None:
            c = np.asarray(self.crosstalk, float)
            if c.shape != (3, 3):
                raise AnalysisError(f"crosstalk has shape {c.shape}: expected (3, 3)")
            object.__setattr__(self, "crosstalk", c)

    @classmethod
    def from_config(
        cls, dyno: Dynamometer, rate_hz: float, with_workpiece: bool = True,
        crosstalk: bool = True, drop_above_nyquist: bool = False,
    ) -> DynamometerFilter:  # fmt: skip
        """From a rig's dynamometer config (modes with or without the workpiece).

        ``drop_above_nyquist``: leave out modes at or above rate/2 (a record sampled that slowly
        cannot show them; its anti-alias filter removed them) instead of refusing.
        """
        modes = dyno.modes if with_workpiece else dyno.modes_without_workpiece
        if drop_above_nyquist:
            modes = tuple(m for m in modes if m.f_hz < rate_hz / 2)
        ct = np.asarray(dyno.crosstalk, float) if (crosstalk and dyno.crosstalk) else None
        if ct is not None and ct.shape != (3, 3):
            ct = None
        return cls(tuple(modes), float(rate_hz), ct)

    @classmethod
    def from_table(
        cls, rate_hz: float, frequencies_hz: Sequence[float], damping: Sequence[float]
    ) -> DynamometerFilter:
        """Modes given as x, y, z frequency (Hz) and damping-ratio lists."""
        modes = tuple(
            Mode(axis=a, f_hz=f, zeta=z)
            for a, f, z in zip(AXES, frequencies_hz, damping)
        )
        return cls(modes, float(rate_hz))

    def apply(self, force_n: ArrayLike) -> np.ndarray:
        """Filter a record. ``force_n`` shape (n, 3) N -> measured (n, 3) N, starting at rest."""
        return self.stream().process(force_n)

    def stream(self) -> FilterState:
        """A stateful filter for consecutive blocks (starts at rest)."""
        zi = [None if ba is None else np.zeros(len(ba[1]) - 1) for ba in self._ba]
        return FilterState(self, zi)

    def frequency_response(self, freq_hz: ArrayLike) -> np.ndarray:
        """Complex response per axis at ``freq_hz`` (shape (k,)) -> (k, 3), without cross-talk."""
        f = np.asarray(freq_hz, float)
        out = np.ones(f.shape + (3,), complex)
        for i, ba in enumerate(self._ba):
            if ba is not None:
                _, h = signal.freqz(ba[0], ba[1], worN=f, fs=self.rate_hz)
                out[..., i] = h
        return out

    def periodic_response(self, waveform: ArrayLike, period_s: float, axis: int = 0) -> np.ndarray:
        """Steady-state response to a periodic force given by ``waveform`` over one period.

        ``waveform`` has the period's samples along ``axis`` (n equally spaced points over
        ``period_s``) and the 3 force axes last: shape (..., n, ..., 3). The n points need not be
        the filter's sample instants: the response is evaluated at the period's harmonics.
        """
        w = np.moveaxis(np.asarray(waveform, float), axis, 0)
        n = w.shape[0]
        spec = np.fft.rfft(w, axis=0)
        key = (spec.shape[0], float(period_s))
        h = self._harmonics.get(key)
        if h is None:
            if len(self._harmonics) >= 64:
                self._harmonics.clear()
            h = self._harmonics[key] = self.frequency_response(np.arange(key[0]) / period_s)
        h = h.reshape((key[0],) + (1,) * (w.ndim - 2) + (3,))
        out = np.fft.irfft(spec * h, n=n, axis=0)
        if self.crosstalk is not None:
            out = out @ self.crosstalk.T
        return np.moveaxis(out, 0, axis)


@dataclass
class FilterState:
    """Running state of a :class:`DynamometerFilter` for block-by-block filtering."""

    filt: DynamometerFilter
    zi: list[NDArray[np.float64] | None]

    def process(self, block_n: ArrayLike) -> np.ndarray:
        """Filter the next block, shape (n, 3) N -> (n, 3) N."""
        x = np.asarray(block_n, float)
        if x.ndim != 2 or x.shape[1] != 3:
            raise AnalysisError(f"force block has shape {x.shape}: expected (n, 3) N")
        y = x.copy()
        for i, ba in enumerate(self.filt._ba):
            if ba is not None:
                y[:, i], self.zi[i] = signal.lfilter(ba[0], ba[1], x[:, i], zi=self.zi[i])
        if self.filt.crosstalk is not None:
            y = y @ self.filt.crosstalk.T
        return y
