"""The hammer test's picture: |H1| and coherence per channel, the identified modes marked."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from analysis.modal.hammer import ModalResult


def plot_frf(result: ModalResult, path: str | Path) -> Path:
    """PNG: |H1| and coherence per channel with modes (receptance for a displacement or
    acceleration response), the identified modes marked."""

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(2, 1, figsize=(9, 6), sharex=True, constrained_layout=True)
    f = result.freq_hz
    names = result.channels or ("x", "y", "z")
    shown = list(dict.fromkeys(m.channel for m in result.modes))
    for k, name in enumerate(shown):
        c = names.index(name)
        ms = [m for m in result.modes if m.channel == name]
        label = f"{name}: " + ", ".join(f"{m.frequency_hz:.0f} Hz (zeta {m.damping_ratio:.4f})"
                                        for m in ms)  # fmt: skip
        a1.semilogy(f, np.abs(result.frf[c]), color=f"C{k}", label=label)
        for m in ms:
            a1.axvline(m.frequency_hz, color=f"C{k}", ls=":", lw=0.8)
        a2.plot(f, result.coherence[c], color=f"C{k}")
    a1.set_ylabel("|H1| (response / hammer; m/N for disp, accel)")
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
