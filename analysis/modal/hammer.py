"""Modes from an impulse-hammer test: a dynamometer's (seed 003 3.2, Table 2) or a tool's.

A record holds the hammer's force and the response channels at one sample rate, with several hits
in one direction. A response is a force (a dynamometer: the FRF is force / force), a displacement
(m) or an acceleration (m/s^2). The steps:

1. ``split_hits``: each hit becomes a record of ``record_s`` starting ``pretrigger_s`` before the
   hammer force crosses ``trigger_frac`` of its peak; hits closer than a record are refused.
2. ``double_hit``: a hit whose hammer force rises again (above ``double_frac`` of the first peak)
   after the pulse has died away is a double hit and is left out (listed in the result).
3. FRF H1 per response channel with coherence, averaged over the hits (pyFRF, which turns an
   accelerance into a receptance by dividing by -w^2), with an exponential window (end value
   ``window_end``) on both channels so the response dies out inside the record; the hammer
   channel is also force-windowed (zero after its pulse) so its noise does not enter the
   cross-spectra. The band analysed ends where the hammer's spectrum falls 20 dB below its peak.
4. Modes per channel: LSCF poles over model orders and a stabilisation diagram
   (:mod:`~analysis.modal.stabilisation`); each cluster of stable poles with good coherence is
   a mode. The exponential window's decay rate sigma_w = -ln(window_end) fs / (n - 1) is
   subtracted from the pole's real part (zeta_true w_n,true = zeta_w w_n,w - sigma_w, same
   damped frequency). Cross-checked by the half-power bandwidth on |H| of the un-windowed
   average where no other mode is within 20 % (a warning if the two disagree by more than 25 %
   in damping or 2 % in frequency).
5. Modal constants by LSFD on the windowed FRF with the windowed poles (the window scales the
   impulse response by exp(-sigma_w t): the poles move, the residues stay). Read as a
   driving-point FRF H(w) = sum_r R_r / (w_r^2 - w^2 + 2 i zeta_r w_r w), R_r = 2 i w_d A_r:
   for a displacement or acceleration response the modal mass m_r = 1 / R_r, stiffness
   k_r = m_r w_r^2, damping c_r = 2 zeta_r sqrt(k_r m_r); for a force response R_r / w_r^2 is
   the mode's share of the static gain (1 for each of seed 003's one-mode axes).
6. ``tooth_passing_warnings``: harmonics of the tooth-passing frequency of planned tests that fall
   within max(10 %, 2 zeta) of a mode.

Units: forces in N, displacement in m, frequencies in Hz, damping as a fraction of critical.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis.errors import AnalysisError

if TYPE_CHECKING:
    from analysis.config import Mode
    from analysis.modal.stabilisation import Stabilisation

__all__ = [
    "MAX_HITS",
    "MIN_RECORD_S",
    "RESPONSES",
    "ImpactRecord",
    "ModalResult",
    "ModeEstimate",
    "double_hit",
    "half_power",
    "modal_analysis",
    "split_hits",
    "tooth_passing_warnings",
]

#: Response kinds: force (N, a dynamometer), disp (m), accel (m/s^2).
RESPONSES = ("force", "disp", "accel")
#: Shortest record per hit: a frequency step of 100 Hz at most, and at least this many samples.
MIN_RECORD_S = 0.01
MIN_RECORD_SAMPLES = 128
#: Most hits in one record (a noisy hammer channel must not make thousands of "hits").
MAX_HITS = 1000


@dataclass(frozen=True)
class ImpactRecord:
    """Hammer force ``hammer_n`` (n,) N and responses ``response`` (n, c) with channel names
    ``channels`` (axis letters x, y, z where known), at ``rate_hz``; ``responses`` the kind of
    each channel (``RESPONSES``, SI units; one kind for all, or one per channel)."""

    hammer_n: np.ndarray
    response: np.ndarray
    rate_hz: float
    channels: tuple[str, ...] = ("x", "y", "z")
    name: str = ""
    responses: tuple[str, ...] | str = "force"


@dataclass(frozen=True)
class ModeEstimate:
    """One mode of a channel: LSCF ``frequency_hz`` and ``damping_ratio`` (window-corrected),
    the raw windowed damping, the half-power cross-check (NaN with a neighbouring mode), mean
    coherence around the mode; ``response`` kind; ``residue`` R_r (FRF unit x (rad/s)^2);
    ``mass_kg``, ``stiffness_n_m``, ``damping_n_s_m`` (NaN for a force response); ``stable_poles``
    how many stable poles its cluster holds; ``frequency_uncertainty_hz`` and
    ``damping_uncertainty``: the standard deviation of the cluster's poles over model orders
    (with the frequency step's resolution), which is all one hit can say (no averaging)."""

    channel: str
    frequency_hz: float
    damping_ratio: float
    damping_windowed: float
    half_power_frequency_hz: float
    half_power_damping: float
    coherence: float
    warnings: tuple[str, ...] = ()
    response: str = "force"
    residue: float = math.nan
    mass_kg: float = math.nan
    stiffness_n_m: float = math.nan
    damping_n_s_m: float = math.nan
    stable_poles: int = 0
    frequency_uncertainty_hz: float = math.nan
    damping_uncertainty: float = math.nan


@dataclass(frozen=True)
class ModalResult:
    """``modes`` of the analysed channels (by channel, ascending in frequency); ``hits_used`` /
    ``double_hits`` (indices into the hits); ``freq_hz`` (k,), ``frf`` (c, k) complex H1
    (receptance for displacement and acceleration), ``coherence`` (c, k); ``skipped`` channels
    with the reason; ``warnings``; ``stabilisation`` per analysed channel name."""

    modes: tuple[ModeEstimate, ...]
    hits_used: tuple[int, ...]
    double_hits: tuple[int, ...]
    freq_hz: np.ndarray
    frf: np.ndarray
    coherence: np.ndarray
    skipped: tuple[tuple[str, str], ...] = ()
    warnings: tuple[str, ...] = field(default_factory=tuple)
    stabilisation: dict[str, Stabilisation] = field(default_factory=dict)
    channels: tuple[str, ...] = ()


def split_hits(
    hammer_n: ArrayLike, rate_hz: float, record_s: float, pretrigger_s: float = 0.0005,
    trigger_frac: float = 0.1,
) -> list[int]:  # fmt: skip
    """Start sample of each hit's record (pretrigger before the hammer crosses the trigger).

    ``record_s`` must hold at least ``MIN_RECORD_SAMPLES`` and ``MIN_RECORD_S`` (a finer
    frequency step than 100 Hz) and fit in the record; at most ``MAX_HITS`` hits."""
    h = np.asarray(hammer_n, float)
    if not (rate_hz > 0 and math.isfinite(rate_hz)):
        raise AnalysisError(f"rate_hz = {rate_hz}: expected a sampling rate > 0 Hz")
    peak = np.abs(h).max() if h.size else 0.0
    if not peak > 0:
        raise AnalysisError("the hammer channel is flat: no hits in the record")
    total_s = len(h) / rate_hz
    shortest_s = max(MIN_RECORD_S, MIN_RECORD_SAMPLES / rate_hz, 2 * pretrigger_s)
    if not shortest_s <= record_s <= total_s:
        raise AnalysisError(
            f"record_s (--record-s) = {record_s:g} s: expected {shortest_s:g} to {total_s:g} s "
            f"(at least {MIN_RECORD_SAMPLES} samples and {MIN_RECORD_S:g} s, at most the "
            f"{total_s:g} s recorded)"
        )
    n_rec, pre = int(round(record_s * rate_hz)), int(round(pretrigger_s * rate_hz))
    idx = np.flatnonzero(np.abs(h) >= trigger_frac * peak)
    starts: list[int] = []
    i = 0
    while (k := int(np.searchsorted(idx, i))) < len(idx):  # i grows by >= 1 record a pass
        s = max(0, int(idx[k]) - pre)
        if s + n_rec <= len(h):
            starts.append(s)
            if len(starts) > MAX_HITS:
                raise AnalysisError(
                    f"more than {MAX_HITS} hits of {record_s:g} s in the record: split the "
                    "file, or is the hammer channel noise?"
                )
        i = max(s + n_rec, int(idx[k]) + 1)
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


def half_power(
    freq_hz: NDArray[np.float64], mag: NDArray[np.float64], lo_hz: float, hi_hz: float
) -> tuple[float, float]:
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


def _h1(
    exc: NDArray[np.float64], resp: NDArray[np.float64], rate_hz: float, window: str,
    resp_type: str = "d",
) -> tuple[NDArray[np.float64], NDArray[np.complex128], NDArray[np.float64]]:  # fmt: skip
    """H1 FRF and coherence with pyFRF: exc (hits, n), resp (hits, c, n) -> f, H (c, k), coh;
    ``resp_type`` 'a' turns an accelerance into a receptance."""
    import pyFRF

    n = exc.shape[-1]
    frf = pyFRF.FRF(
        sampling_freq=int(round(rate_hz)), exc_type="f", resp_type=resp_type,
        window=(window, window), frf_estimator="H1", fft_len=n,
    )  # fmt: skip
    with np.errstate(divide="ignore", invalid="ignore"):
        frf.add_data(exc[:, None, :], resp)
        h = frf.get_FRF(frf_form="receptance")[:, 0, :]
        coh = frf.get_coherence()
    return frf.get_f_axis(), h, coh


def _response_kinds(record: ImpactRecord, n_channels: int) -> tuple[str, ...]:
    kinds = record.responses
    kinds = (kinds,) * n_channels if isinstance(kinds, str) else tuple(kinds)
    if len(kinds) != n_channels:
        raise AnalysisError(f"{len(kinds)} response kinds for {n_channels} channels")
    for k in kinds:
        if k not in RESPONSES:
            raise AnalysisError(f"response kind {k!r}: expected one of {', '.join(RESPONSES)}")
    return kinds


def _hammer_band_hz(exc: np.ndarray, rate_hz: float) -> float:
    """Upper end of the band the hammer excites: where its spectrum first falls 20 dB below the
    peak (beyond it, near the pulse's spectral zeros, H1 is noise over nothing), at most
    0.45 fs."""
    power = np.mean(np.abs(np.fft.rfft(exc, axis=-1)) ** 2, axis=0)
    f = np.fft.rfftfreq(exc.shape[-1], 1.0 / rate_hz)
    low = np.flatnonzero(power < 0.01 * power.max())
    return float(min(f[low[0]] if len(low) else np.inf, 0.45 * rate_hz))


def _mode_frf(
    residue: float, f_hz: float, zeta: float, at_hz: ArrayLike
) -> NDArray[np.complex128]:
    """R / (w_r^2 - w^2 + 2 i zeta w_r w): one mode's part of a driving-point FRF."""
    wr, w = 2 * math.pi * f_hz, 2 * math.pi * np.asarray(at_hz, float)
    return np.asarray(residue / (wr * wr - w * w + 2j * zeta * wr * w), np.complex128)


def _channel_modes(
    name: str, kind: str, st: Stabilisation, freq: np.ndarray, frf_raw: np.ndarray, coh: np.ndarray,
    sigma_w: float, min_coherence: float, notes: list[str],
) -> list[ModeEstimate]:  # fmt: skip
    """The stabilisation's modes of one channel with the window's damping taken out, coherence
    checked, LSFD constants as mass, stiffness and damping, the half-power cross-check."""
    from analysis.modal.stabilisation import modal_constants

    lo, hi = st.band_hz
    df = float(freq[1] - freq[0])
    chosen = []  # (pole index pair, f_true, z_true, z_windowed, coherence, cluster size)
    for j, (o, i) in enumerate(st.modes):
        fw, zw = float(st.freq_hz[o][i]), float(st.damping[o][i])
        sigma = zw * 2 * math.pi * fw - sigma_w
        f_true = math.hypot(sigma, st.poles[o][i].imag) / (2 * math.pi)
        z_true = sigma / (2 * math.pi * f_true)
        around = (freq >= lo) & (freq <= hi) & (np.abs(freq - fw) <= max(2 * zw * fw, 2 * df))
        coh_m = float(np.nanmean(coh[around])) if around.any() else math.nan
        if not z_true > 0:
            notes.append(
                f"{name}: pole at {fw:.0f} Hz left out: damping {zw:.4f} is the exponential "
                "window's; use a longer --record-s or a larger --window-end"
            )
        elif not coh_m >= min_coherence:
            notes.append(f"{name}: pole at {fw:.0f} Hz left out: coherence {coh_m:.2f} below "
                         f"{min_coherence}")  # fmt: skip
        else:
            chosen.append(((o, i), f_true, z_true, zw, coh_m, st.cluster_size(j)))
    if not chosen:
        return []
    a_r = modal_constants(st, [m[0] for m in chosen])
    # R_r = 2 i w_d A_r: sdypy-EMA's A_r / (i w - s_r) + c.c. written R_r / (w_r^2 - w^2 + ...)
    res = [float((2j * st.poles[o][i].imag * a).real) for ((o, i), *_), a in zip(chosen, a_r)]
    out = []
    for (_, f_true, z_true, zw, coh_m, size), residue in zip(chosen, res):
        wn = 2 * math.pi * f_true
        w = []
        mass = stiff = damp = math.nan
        if kind != "force" and residue > 0:
            mass = 1.0 / residue
            stiff = mass * wn * wn
            damp = 2 * z_true * math.sqrt(stiff * mass)
        elif kind != "force":
            w.append(f"{name}: mode at {f_true:.0f} Hz has residue {residue:.3g} <= 0: not a "
                     "driving-point FRF (hammer and sensor apart?); no modal mass")  # fmt: skip
        # Half-power only where the other modes add < 10 % to this one's peak.
        others: complex = sum(complex(_mode_frf(r, m[1], m[2], f_true)) for r, m in zip(res, chosen)
                              if m[1] != f_true)  # fmt: skip
        fh = zh = math.nan
        if abs(others) < 0.1 * abs(_mode_frf(residue, f_true, z_true, f_true)):
            fh, zh = half_power(freq, np.abs(frf_raw), max(lo, 0.8 * f_true),
                                min(hi, 1.2 * f_true))  # fmt: skip
            if abs(fh - f_true) > 0.02 * f_true:
                w.append(f"{name}: LSCF {f_true:.0f} Hz vs half-power peak {fh:.0f} Hz")
            if math.isfinite(zh) and abs(zh - z_true) > 0.25 * z_true:
                w.append(f"{name}: LSCF damping {z_true:.4f} vs half-power {zh:.4f}")
            if not math.isfinite(zh):
                w.append(f"{name}: half-power points outside the band; no cross-check")
        sf, sz = _cluster_spread(st, f_true, df)
        out.append(ModeEstimate(name, f_true, z_true, zw, fh, zh, coh_m, tuple(w), kind, residue,
                                mass, stiff, damp, size, sf, sz))  # fmt: skip
        notes.extend(w)
    return out


def _cluster_spread(st: Stabilisation, f_hz: float, df_hz: float) -> tuple[float, float]:
    """Standard deviation of frequency (with the step's resolution, df / sqrt(12)) and of
    damping over the counted poles within the stabilisation's tolerance of ``f_hz``."""
    from analysis.modal.stabilisation import FREQ_TOL

    fs, zs = [], []
    for fr, xi, state in zip(st.freq_hz, st.damping, st.state):
        near = (state == 4) & (np.abs(fr - f_hz) <= FREQ_TOL * f_hz)
        fs.extend(fr[near])
        zs.extend(xi[near])
    if len(fs) < 2:
        return math.nan, math.nan
    return (float(math.hypot(np.std(fs, ddof=1), df_hz / math.sqrt(12))),
            float(np.std(zs, ddof=1)))  # fmt: skip


def _force_window(exc: NDArray[np.float64], rate: float) -> None:
    """Force window, in place: each hit's hammer channel is zero from 0.5 ms after its pulse
    falls below 2 % of the peak (its noise is not excitation)."""
    for row in exc:
        k = int(np.argmax(np.abs(row)))
        below = np.flatnonzero(np.abs(row[k:]) < 0.02 * np.abs(row[k]))
        if len(below):
            row[k + int(below[0]) + int(0.0005 * rate) :] = 0.0


def _one_hit_note(modes: list[ModeEstimate]) -> str:
    """The warning of a one-hit record: no coherence, the spread over model orders only."""
    spread = "; ".join(
        f"{m.channel} {m.frequency_hz:.0f} +- {m.frequency_uncertainty_hz:.1f} Hz, damping "
        f"{m.damping_ratio:.4f} +- {m.damping_uncertainty:.4f}" for m in modes
    )  # fmt: skip
    return (
        "one hit: no coherence (it needs at least 2 hits) and the noise is not averaged; "
        f"the uncertainty is the spread over model orders only ({spread or 'no mode'}): "
        "tap 3-5 times for a coherence check"
    )


def modal_analysis(
    record: ImpactRecord,
    record_s: float = 0.08,
    pretrigger_s: float = 0.0005,
    window_end: float = 0.05,
    band_hz: tuple[float, float] | None = None,
    min_coherence: float = 0.9,
) -> ModalResult:
    """Modes of each response channel from the hits of an impulse-hammer record."""
    from analysis.modal.stabilisation import stabilise

    rate = float(record.rate_hz)
    h = np.asarray(record.hammer_n, float)
    y = np.asarray(record.response, float)
    if y.ndim == 1:
        y = y[:, None]
    if len(h) != len(y):
        raise AnalysisError(f"hammer has {len(h)} samples, responses {len(y)}: must match")
    if not 0 < window_end <= 1:
        raise AnalysisError(f"window_end = {window_end}: expected 0 < end value <= 1")
    names = tuple(record.channels[: y.shape[1]])
    kinds = _response_kinds(record, y.shape[1])
    starts = split_hits(h, rate, record_s, pretrigger_s)
    n = int(round(record_s * rate))
    doubles = [i for i, s in enumerate(starts) if double_hit(h[s : s + n], rate)]
    used = [i for i in range(len(starts)) if i not in doubles]
    notes: list[str] = []
    if doubles:
        notes.append(f"double hit(s) left out: {', '.join(str(i) for i in doubles)}")
    if not used:
        raise AnalysisError(
            f"no usable hit ({len(doubles)} double): tap again, one clean hit at least"
        )
    exc = np.stack([h[starts[i] : starts[i] + n] for i in used])
    resp = np.stack([y[starts[i] : starts[i] + n].T for i in used])
    _force_window(exc, rate)
    win = f"exponential:{window_end}"
    frf = np.zeros((y.shape[1], n // 2 + 1), complex)
    frf_raw, coh = np.zeros_like(frf), np.zeros(frf.shape)
    for kind in set(kinds):
        cs = [c for c in range(y.shape[1]) if kinds[c] == kind]
        rt = "a" if kind == "accel" else "d"
        freq, frf[cs], coh[cs] = _h1(exc, resp[:, cs], rate, win, rt)
        frf_raw[cs] = _h1(exc, resp[:, cs], rate, "none", rt)[1]
    sigma_w = -math.log(window_end) * rate / (n - 1)
    lo, hi = band_hz if band_hz else (max(freq[1] * 4, 50.0), _hammer_band_hz(exc, rate))
    band = (freq >= lo) & (freq <= hi)
    modes: list[ModeEstimate] = []
    skipped, stabs = [], {}
    for c, name in enumerate(names):
        mag = np.abs(np.nan_to_num(frf[c]))
        if kinds[c] == "accel":  # the peak as measured: receptance noise grows as 1 / w^2
            mag = mag * freq**2
        k = int(np.argmax(np.where(band, mag, 0)))
        f_peak = float(freq[k])
        near = band & (np.abs(freq - f_peak) <= 0.2 * f_peak)
        coh_c = float(np.nanmean(coh[c][near]))
        if not coh_c >= min_coherence:
            skipped.append((name, (
                f"no mode: coherence {coh_c:.2f} below {min_coherence} near the peak "
                f"({f_peak:.0f} Hz): channel not excited by these hits"
            )))  # fmt: skip
            continue
        st = stabilise(freq, frf[c], (lo, hi), "receptance")
        stabs[name] = st
        found = _channel_modes(name, kinds[c], st, freq, frf_raw[c], coh[c], sigma_w,
                               min_coherence, notes)  # fmt: skip
        if not found:
            skipped.append((name, f"no mode: no stable pole with coherence >= {min_coherence} in "
                                  f"{lo:.0f}..{hi:.0f} Hz"))  # fmt: skip
        modes.extend(found)
    if len(used) == 1:  # an H1 of one hit has coherence 1 by construction: nothing checked
        notes.insert(0, _one_hit_note(modes))
    return ModalResult(tuple(modes), tuple(used), tuple(doubles), freq, frf, coh,
                       tuple(skipped), tuple(notes), stabs, names)  # fmt: skip


def tooth_passing_warnings(
    modes: Sequence[Mode | ModeEstimate], spindle_rpm: ArrayLike, teeth: int, harmonics: int = 10,
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
