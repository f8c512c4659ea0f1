"""Dynamometer modes from an impulse-hammer test (seed 003 3.2, Table 2).

A record holds the hammer's force and the dynamometer's response channels at one sample rate,
with several hits in one direction. The steps:

1. ``split_hits``: each hit becomes a record of ``record_s`` starting ``pretrigger_s`` before the
   hammer force crosses ``trigger_frac`` of its peak; hits closer than a record are refused.
2. ``double_hit``: a hit whose hammer force rises again (above ``double_frac`` of the first peak)
   after the pulse has died away is a double hit and is left out (listed in the result).
3. FRF H1 per response channel with coherence, averaged over the hits (pyFRF), with an
   exponential window (end value ``window_end``) on both channels so the response dies out inside
   the record; the hammer channel is also force-windowed (zero after its pulse) so its noise does
   not enter the cross-spectra.
4. Natural frequency and damping per channel: LSCF poles (sdypy-EMA) nearest the FRF's peak; the
   exponential window's decay rate sigma_w = -ln(window_end) fs / (n - 1) is subtracted from the
   pole's real part (zeta_true w_n,true = zeta_w w_n,w - sigma_w, same damped frequency).
   Cross-checked by the half-power bandwidth on |H| of the un-windowed average (a warning if the
   two disagree by more than 25 % in damping or 2 % in frequency).
5. ``tooth_passing_warnings``: harmonics of the tooth-passing frequency of planned tests that fall
   within max(10 %, 2 zeta) of a mode.

Units: forces in N, frequencies in Hz, damping as a fraction of critical.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from analysis.errors import AnalysisError

__all__ = [
    "ImpactRecord",
    "ModalResult",
    "ModeEstimate",
    "double_hit",
    "half_power",
    "modal_analysis",
    "plot_frf",
    "split_hits",
    "tooth_passing_warnings",
]


@dataclass(frozen=True)
class ImpactRecord:
    """Hammer force ``hammer_n`` (n,) N and responses ``response`` (n, c) (N for a dynamometer)
    with channel names ``channels`` (axis letters x, y, z where known), at ``rate_hz``."""

    hammer_n: np.ndarray
    response: np.ndarray
    rate_hz: float
    channels: tuple[str, ...] = ("x", "y", "z")
    name: str = ""


@dataclass(frozen=True)
class ModeEstimate:
    """One channel's mode: LSCF ``frequency_hz`` and ``damping_ratio`` (window-corrected), the
    raw windowed damping, the half-power cross-check, mean coherence around the mode."""

    channel: str
    frequency_hz: float
    damping_ratio: float
    damping_windowed: float
    half_power_frequency_hz: float
    half_power_damping: float
    coherence: float
    warnings: tuple[str, ...] = ()


@dataclass(frozen=True)
class ModalResult:
    """``modes`` per analysed channel; ``hits_used`` / ``double_hits`` (indices into the hits);
    ``freq_hz`` (k,), ``frf`` (c, k) complex H1, ``coherence`` (c, k); ``skipped`` channels with
    the reason; ``warnings``."""

    modes: tuple[ModeEstimate, ...]
    hits_used: tuple[int, ...]
    double_hits: tuple[int, ...]
    freq_hz: np.ndarray
    frf: np.ndarray
    coherence: np.ndarray
    skipped: tuple[tuple[str, str], ...] = ()
    warnings: tuple[str, ...] = field(default_factory=tuple)


def split_hits(
    hammer_n: ArrayLike, rate_hz: float, record_s: float, pretrigger_s: float = 0.0005,
    trigger_frac: float = 0.1,
) -> list[int]:  # fmt: skip
    """Start sample of each hit's record (pretrigger before the hammer crosses the trigger)."""
    h = np.asarray(hammer_n, float)
    peak = np.abs(h).max() if h.size else 0.0
    if peak <= 0:
        raise AnalysisError("the hammer channel is flat: no hits in the record")
    n_rec, pre = int(round(record_s * rate_hz)), int(round(pretrigger_s * rate_hz))
    above = np.abs(h) >= trigger_frac * peak
    starts, i = [], 0
    idx = np.flatnonzero(above)
    while True:
        j = idx[np.searchsorted(idx, i)] if np.searchsorted(idx, i) < len(idx) else None
        if j is None:
            break
        s = max(0, int(j) - pre)
        if s + n_rec <= len(h):
            starts.append(s)
        i = s + n_rec
    if not starts:
        raise AnalysisError(
            f"no complete hit: records of {record_s} s do not fit after any hammer trigger"
        )
    return starts


def double_hit(pulse_n: ArrayLike, rate_hz: float, double_frac: float = 0.1) -> bool:
    """True if the hammer force rises again after its first pulse has died away.

    The first pulse ends where the force falls below 2 % of its peak; any later sample above
    ``double_frac`` of the peak is a second impact (the hammer bounced).
    """
    x = np.abs(np.asarray(pulse_n, float))
    k = int(np.argmax(x))
    peak = x[k]
    below = np.flatnonzero(x[k:] < 0.02 * peak)
    if len(below) == 0:
        return False
    end = k + int(below[0])
    return bool(np.any(x[end:] > double_frac * peak))


def half_power(freq_hz: np.ndarray, mag: np.ndarray, lo_hz: float, hi_hz: float):
    """Peak frequency and damping from the half-power (-3 dB) bandwidth of |H| in [lo, hi].

    zeta = (f2 - f1) / (2 f_peak), with the crossings linearly interpolated. NaN if a crossing
    lies outside the band.
    """
    band = (freq_hz >= lo_hz) & (freq_hz <= hi_hz)
    f, m = freq_hz[band], mag[band]
    if len(f) < 5:
        return math.nan, math.nan
    k = int(np.argmax(m))
    if 0 < k < len(m) - 1:  # parabolic peak
        y0, y1, y2 = m[k - 1], m[k], m[k + 1]
        den = y0 - 2 * y1 + y2
        off = 0.5 * (y0 - y2) / den if den != 0 else 0.0
        fp = f[k] + off * (f[1] - f[0])
        mp = y1 - 0.25 * (y0 - y2) * off
    else:
        fp, mp = f[k], m[k]
    level = mp / math.sqrt(2)
    left = np.flatnonzero(m[:k] < level)
    right = np.flatnonzero(m[k:] < level)
    if len(left) == 0 or len(right) == 0:
        return float(fp), math.nan
    i = int(left[-1])
    f1 = f[i] + (level - m[i]) * (f[i + 1] - f[i]) / (m[i + 1] - m[i])
    j = k + int(right[0])
    f2 = f[j - 1] + (level - m[j - 1]) * (f[j] - f[j - 1]) / (m[j] - m[j - 1])
    return float(fp), float((f2 - f1) / (2 * fp))


def _h1(exc: np.ndarray, resp: np.ndarray, rate_hz: float, window: str):
    """H1 FRF and coherence with pyFRF: exc (hits, n), resp (hits, c, n) -> f, H (c, k), coh."""
    import pyFRF

    n = exc.shape[-1]
    frf = pyFRF.FRF(
        sampling_freq=int(round(rate_hz)), exc_type="f", resp_type="d",
        window=(window, window), frf_estimator="H1", fft_len=n,
    )  # fmt: skip
    frf.add_data(exc[:, None, :], resp)
    h = frf.get_FRF(frf_form="receptance")[:, 0, :]
    coh = frf.get_coherence()
    return frf.get_f_axis(), h, coh


def _lscf(freq: np.ndarray, h: np.ndarray, f_guess: float, lo: float, hi: float):
    """LSCF pole nearest ``f_guess`` (sdypy-EMA): (frequency Hz, damping ratio)."""
    from sdypy import EMA

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # EMA warns about ill-conditioned high orders
        model = EMA.Model(frf=h[None, :], freq=freq, lower=lo, upper=hi, pol_order_high=30,
                          frf_form="receptance")  # fmt: skip
        import contextlib
        import io

        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            model.get_poles(method="lscf", show_progress=False)
            model.select_closest_poles([f_guess], f_window=max(50.0, 0.1 * f_guess))
    return float(model.nat_freq[0]), float(model.nat_xi[0])


def modal_analysis(
    record: ImpactRecord,
    record_s: float = 0.08,
    pretrigger_s: float = 0.0005,
    window_end: float = 0.05,
    band_hz: tuple[float, float] | None = None,
    min_coherence: float = 0.9,
) -> ModalResult:
    """Modes of each response channel from the hits of an impulse-hammer record."""
    rate = float(record.rate_hz)
    h = np.asarray(record.hammer_n, float)
    y = np.asarray(record.response, float)
    if y.ndim == 1:
        y = y[:, None]
    if len(h) != len(y):
        raise AnalysisError(f"hammer has {len(h)} samples, responses {len(y)}: must match")
    if not 0 < window_end <= 1:
        raise AnalysisError(f"window_end = {window_end}: expected 0 < end value <= 1")
    starts = split_hits(h, rate, record_s, pretrigger_s)
    n = int(round(record_s * rate))
    doubles = [i for i, s in enumerate(starts) if double_hit(h[s : s + n], rate)]
    used = [i for i in range(len(starts)) if i not in doubles]
    notes: list[str] = []
    if doubles:
        notes.append(f"double hit(s) left out: {', '.join(str(i) for i in doubles)}")
    if len(used) < 2:
        raise AnalysisError(
            f"{len(used)} usable hit(s) ({len(doubles)} double): need at least 2 for an H1 "
            "average with coherence"
        )
    exc = np.stack([h[starts[i] : starts[i] + n] for i in used])
    resp = np.stack([y[starts[i] : starts[i] + n].T for i in used])
    # Force window: the hammer channel is zero after its pulse (its noise is not excitation).
    for row in exc:
        k = int(np.argmax(np.abs(row)))
        below = np.flatnonzero(np.abs(row[k:]) < 0.02 * np.abs(row[k]))
        if len(below):
            row[k + int(below[0]) + int(0.0005 * rate) :] = 0.0
    win = f"exponential:{window_end}"
    freq, frf, coh = _h1(exc, resp, rate, win)
    _, frf_raw, _ = _h1(exc, resp, rate, "none")
    sigma_w = -math.log(window_end) * rate / (n - 1)
    lo, hi = band_hz if band_hz else (max(freq[1] * 4, 50.0), 0.45 * rate)
    modes, skipped = [], []
    for c, name in enumerate(record.channels[: y.shape[1]]):
        band = (freq >= lo) & (freq <= hi)
        mag = np.abs(frf[c])
        k = int(np.argmax(np.where(band, mag, 0)))
        f_peak = float(freq[k])
        near = band & (np.abs(freq - f_peak) <= 0.2 * f_peak)
        coh_c = float(np.nanmean(coh[c][near]))
        if not coh_c >= min_coherence:
            why = (
                f"coherence {coh_c:.2f} below {min_coherence} near the peak ({f_peak:.0f} Hz): "
                "channel not excited by these hits"
            )
            skipped.append((name, why))
            continue
        fw, zw = _lscf(freq, frf[c], f_peak, lo, hi)
        wd = 2 * math.pi * fw * math.sqrt(max(1 - zw * zw, 0.0))
        sigma = zw * 2 * math.pi * fw - sigma_w
        wn = math.hypot(sigma, wd)
        f_true, z_true = wn / (2 * math.pi), sigma / wn
        fh, zh = half_power(freq, np.abs(frf_raw[c]), lo, hi)
        w = []
        if abs(fh - f_true) > 0.02 * f_true:
            w.append(f"{name}: LSCF {f_true:.0f} Hz vs half-power peak {fh:.0f} Hz")
        if math.isfinite(zh) and abs(zh - z_true) > 0.25 * z_true:
            w.append(f"{name}: LSCF damping {z_true:.4f} vs half-power {zh:.4f}")
        if not math.isfinite(zh):
            w.append(f"{name}: half-power points outside the band; no cross-check")
        modes.append(ModeEstimate(name, f_true, z_true, zw, fh, zh, coh_c, tuple(w)))
        notes.extend(w)
    return ModalResult(tuple(modes), tuple(used), tuple(doubles), freq, frf, coh,
                       tuple(skipped), tuple(notes))  # fmt: skip


def tooth_passing_warnings(
    modes: Sequence, spindle_rpm: ArrayLike, teeth: int, harmonics: int = 10,
    margin: float = 0.1,
) -> list[str]:  # fmt: skip
    """Warnings for harmonics k * rpm / 60 * teeth (k = 1..harmonics) of planned tests that lie
    within max(margin, 2 zeta) of a mode (``Mode`` configs or ``ModeEstimate``)."""
    out = []
    for rpm in np.atleast_1d(np.asarray(spindle_rpm, float)):
        ftp = abs(rpm) / 60.0 * teeth
        for m in modes:
            fn, z = float(m.frequency_hz), float(m.damping_ratio)
            tol = max(margin, 2 * z) * fn
            for k in range(1, harmonics + 1):
                if abs(k * ftp - fn) <= tol:
                    axis = getattr(m, "axis", getattr(m, "channel", "?"))
                    out.append(
                        f"{rpm:g} rpm x {teeth} teeth (tooth-passing frequency {ftp:.4g} Hz): "
                        f"harmonic {k} = {k * ftp:.0f} Hz is within {tol:.0f} Hz of the {axis} "
                        f"mode at {fn:.0f} Hz; measured forces will be amplified"
                    )
    return out


def plot_frf(result: ModalResult, path):
    """PNG: |H1| and coherence per analysed channel, with the identified modes marked."""
    from pathlib import Path

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(2, 1, figsize=(9, 6), sharex=True, constrained_layout=True)
    f = result.freq_hz
    for k, m in enumerate(result.modes):
        c = ["x", "y", "z"].index(m.channel) if m.channel in ("x", "y", "z") else k
        a1.semilogy(f, np.abs(result.frf[c]), color=f"C{k}", label=f"{m.channel}: "
                    f"{m.frequency_hz:.0f} Hz, zeta {m.damping_ratio:.4f}")  # fmt: skip
        a1.axvline(m.frequency_hz, color=f"C{k}", ls=":", lw=0.8)
        a2.plot(f, result.coherence[c], color=f"C{k}")
    a1.set_ylabel("|H1| (response / hammer)")
    a1.legend(fontsize=8)
    a1.grid(True, which="both", alpha=0.3)
    a2.set_ylabel("coherence")
    a2.set_xlabel("frequency, Hz")
    a2.set_ylim(0, 1.05)
    a2.grid(True, alpha=0.3)
    out = Path(path)
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return out
