"""From true cutting forces to the volts the DAQ reads: dynamometer modes, cross-talk, charge
amplifier scaling, and the amplifier's noise, drift and mains hum.

The modes are :class:`analysis.modal.filter.DynamometerFilter` (one unit-DC-gain second-order mode
per axis, zero-order hold), run ``oversample`` times faster than the DAQ on forces computed that
often, then every so many-th sample kept: the dynamometer answers to the force between samples (a
face-mill insert enters the workpiece within a sample), as the face-mill fit assumes; its state
carries across blocks so consecutive reads form one continuous signal. Then
``measured = crosstalk @ filtered`` (rows: channel), each channel
takes its axis with its sign, and ``volts = newtons / range_n_v`` (the amplifier is set to the
sensor's sensitivity, so pC cancel): :class:`rig.daq.calibration.Calibration` run forwards.
"""

from __future__ import annotations

import numpy as np

from analysis.config import Dynamometer
from analysis.modal import DynamometerFilter
from rig.daq import Calibration

_AXES = {"x": 0, "y": 1, "z": 2}


class DynoChain:
    """Stateful force -> volts chain at a fixed sample rate.

    Parameters: ``dyno`` (channels, modes, cross-talk), ``rate_hz``; ``noise_n`` rms white noise,
    ``drift_n_s`` linear drift, ``hum_n`` amplitude of ``hum_hz`` mains hum, all in newtons at the
    amplifier output; ``seed`` for the noise; ``modes`` False bypasses the dynamometer's dynamics;
    ``oversample``: forces given to :meth:`volts` come that many per DAQ sample.
    """

    def __init__(
        self,
        dyno: Dynamometer,
        rate_hz: float,
        noise_n: float = 0.0,
        drift_n_s: float = 0.0,
        hum_n: float = 0.0,
        hum_hz: float = 50.0,
        seed: int = 0,
        modes: bool = True,
        oversample: int = 1,
    ) -> None:
        self.dyno = dyno
        self.rate_hz = float(rate_hz)
        self.noise_n = noise_n
        self.drift_n_s = drift_n_s
        self.hum_n = hum_n
        self.hum_hz = hum_hz
        self.oversample = max(1, int(oversample))
        self._rng = np.random.default_rng(seed)
        self._hum_phase = self._rng.uniform(0, 2 * np.pi, len(dyno.channels))
        # The modes are analysis.modal.filter' filter; cross-talk is left to the calibration below.
        self._modes = (
            DynamometerFilter.from_config(dyno, rate_hz * self.oversample, crosstalk=False)
            if modes
            else None
        )
        self._state = self._modes.stream() if self._modes is not None else None
        # The amplifier chain (sign, cross-talk, sensitivity, range) is the DAQ's calibration run
        # forwards, so the logger's inverse recovers the filtered force exactly.
        self.calibration = Calibration.from_dynamometer(dyno)
        self._axes = np.asarray([_AXES[ch.axis] for ch in dyno.channels])
        self._t_next: float | None = None

    @property
    def channel_names(self) -> list[str]:
        return [ch.name for ch in self.dyno.channels]

    def filtered(self, force_n: np.ndarray, t0_s: float) -> np.ndarray:
        """Pass forces (n * oversample, 3) N through the modes and keep the DAQ's samples (n, 3);
        the state continues if ``t0_s`` follows the last block, otherwise the filter restarts from
        rest (a gap in the samples)."""
        k = self.oversample
        n = force_n.shape[0] // k
        contiguous = self._t_next is not None and abs(t0_s - self._t_next) < 0.5 / self.rate_hz
        self._t_next = t0_s + n / self.rate_hz
        if self._modes is None:
            return np.array(force_n[::k], dtype=float)
        if not contiguous:
            self._state = self._modes.stream()
        assert self._state is not None  # with modes, a stream is set (above or in __init__)
        return self._state.process(force_n)[::k]

    def volts(self, force_n: np.ndarray, t0_s: float) -> np.ndarray:
        """Volts (channels, n) for true forces (n * oversample, 3) N sampled from ``t0_s`` at
        ``oversample`` x the rate."""
        f = self.filtered(force_n, t0_s)[:, self._axes]
        n = f.shape[0]  # (n, channels) in cutlab axes
        t = t0_s + np.arange(n) / self.rate_hz
        # Amplifier drift, hum and noise are disturbances at the output, given in newtons.
        extra = self.drift_n_s * t[:, None] + self.hum_n * np.sin(
            2 * np.pi * self.hum_hz * t[:, None] + self._hum_phase
        )
        if self.noise_n:
            extra = extra + self._rng.normal(0.0, self.noise_n, f.shape)
        volts = self.calibration.volts_from_force(f)
        return (volts + extra / self.calibration.range_n_v).T
