"""The simulated rig's impulse-hammer (tap) test of the tool: a hammer force record and the
tool-tip response of the twin's modes, written as a CSV that `cutlab analyze modal` reads.

One record per direction (the hammer strikes the tool tip along x, the sensor reads x): a few
half-sine hammer pulses of random height and spacing, the response of that direction's modes
(:class:`analysis.config.ToolMode`) marched with the same exact zero-order-hold steps as the
cutting twin (:func:`rig.sim._regen.modal_zoh`) at ``OVERSAMPLE`` steps per sample (the pulse
is resolved, then every ``OVERSAMPLE``-th step is kept), and white noise on both channels.

Columns: ``time_s``, ``hammer [N]`` and ``d<axis> [m]`` (displacement, a laser or capacitive
probe) or ``a<axis> [m/s^2]`` (an accelerometer).

``python -m rig.sim tap TOOL AXIS OUT.csv`` taps the twin's own structure for a catalogue tool
(:mod:`rig.sim.structure`): how the shipped tools' catalogue modes were measured (issue 28).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import scipy.signal

from analysis.config import ToolMode
from analysis.errors import ConfigError
from rig.sim._regen import modal_zoh

__all__ = ["tap_test_record", "tap_twin"]

#: Internal steps per output sample: a 0.2 ms pulse spans ~40 steps at 51.2 kHz.
OVERSAMPLE = 4
PULSE_S = 0.0002  # a steel tip: a flat hammer spectrum to ~5 kHz
HIT_SPACING_S = 0.12  # longer than analyze modal's 0.08 s record per hit


def tap_test_record(
    modes: tuple[ToolMode, ...], axis: str, path: str | Path, response: str = "disp",
    rate_hz: float = 51_200.0, hits: int = 5, noise: float = 0.002, seed: int = 0,
) -> Path:  # fmt: skip
    """Write the tap record of ``axis`` ('x' or 'y') of ``modes`` to ``path`` (CSV, module
    docstring). ``noise``: the response noise's standard deviation as a fraction of its peak;
    the hammer channel gets 0.05 N rms."""
    own = tuple(m for m in modes if m.axis == axis)
    if not own:
        raise ConfigError(f"tap test: no tool mode in direction {axis!r} to excite")
    if response not in ("disp", "accel"):
        raise ConfigError(f"tap test: response = {response!r}: expected 'disp' or 'accel'")
    rng = np.random.default_rng(seed)
    n = int(round((hits + 1) * HIT_SPACING_S * rate_hz))
    dt = 1.0 / (rate_hz * OVERSAMPLE)
    t = np.arange(n * OVERSAMPLE) * dt
    force = np.zeros_like(t)
    for k in range(hits):
        t0 = (k + 0.3) * HIT_SPACING_S + rng.uniform(0.0, 0.005)
        on = (t >= t0) & (t < t0 + PULSE_S)
        force[on] = rng.uniform(80.0, 120.0) * np.sin(math.pi * (t[on] - t0) / PULSE_S)
    ad, bd = modal_zoh(own, dt)
    resp_full = np.zeros_like(t)
    for m, a, b in zip(own, ad, bd):
        # Each mode's state recursion as a digital filter of the force (C code, not a loop):
        # displacement mm = x; acceleration mm/s^2 = gain f - w^2 x - 2 zeta w v.
        w = 2 * math.pi * m.f_hz
        if response == "disp":
            c, d = np.array([[1.0, 0.0]]), np.array([[0.0]])
        else:
            c, d = np.array([[-(w**2), -2 * m.zeta * w]]), np.array([[w**2 * 1e3 / m.k_N_m]])
        num, den = scipy.signal.ss2tf(a, b[:, None], c, d)
        resp_full += scipy.signal.lfilter(num[0], den, force)
    keep = slice(None, None, OVERSAMPLE)
    resp = resp_full[keep] * 1e-3  # m or m/s^2
    resp = resp + rng.normal(0.0, noise * np.abs(resp).max(), resp.shape)
    ham = force[keep] + rng.normal(0.0, 0.05, resp.shape)
    col = f"d{axis} [m]" if response == "disp" else f"a{axis} [m/s^2]"
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(out, np.column_stack([t[keep], ham, resp]), delimiter=",", fmt="%.9g",
               header=f"time_s,hammer [N],{col}", comments="")  # fmt: skip
    return out


def tap_twin(
    tool_name: str, axis: str, path: str | Path, rate_hz: float = 12_800.0, seed: int = 0,
    tools_path: str | Path | None = None,
) -> Path:  # fmt: skip
    """Tap the twin's own structure of catalogue tool ``tool_name`` along ``axis`` (tool-tip
    displacement) into ``path``."""
    from analysis.config import get_tool
    from rig.sim.structure import twin_modes

    modes = twin_modes(get_tool(tool_name, tools_path))
    if not modes:
        raise ConfigError(f"tap test: the twin has no structure for tool {tool_name!r} "
                          "(rig/sim/structure.toml)")  # fmt: skip
    return tap_test_record(modes, axis, path, "disp", rate_hz, seed=seed)

