"""Synthetic feed sweeps for the feed-rule tests (seed 001 Table 2 and Fig. 8)."""

from __future__ import annotations

import numpy as np

from analysis.rules.basefeed import SweepRun

RPM, FLUTES, FS = 2000.0, 2, 10_000.0
FEEDS = np.arange(400, 2201, 200.0)  # seed 001 Table 2: 400..2200 mm/min in 10 steps


def slot_forces(fz_mm: float, seconds: float, rng: np.random.Generator) -> np.ndarray:
    """Feed and cross-feed force of a 2-flute slot (linear edge-force model, no helix)."""
    kt, kr, kte, kre, a = 1100.0, 420.0, 22.0, 28.0, 2.0  # N/mm^2, N/mm, mm (effective width)
    t = np.arange(int(seconds * FS)) / FS
    phi0 = 2 * np.pi * RPM / 60 * t
    fx = np.zeros_like(t)
    fy = np.zeros_like(t)
    for j in range(FLUTES):
        phi = np.mod(phi0 + 2 * np.pi * j / FLUTES, 2 * np.pi)
        eng = phi < np.pi  # slotting: engaged over half a revolution
        h = fz_mm * np.sin(phi)
        ft = (kt * a * h + kte * a) * eng
        fr = (kr * a * h + kre * a) * eng
        fx += -ft * np.cos(phi) - fr * np.sin(phi)
        fy += ft * np.sin(phi) - fr * np.cos(phi)
    return np.column_stack([fx, fy]) + rng.normal(0, 1.0, (len(t), 2))


def sweep(
    change_at: float | None, vib_jump: bool = True, slope_jump: bool = True, seed: int = 1
) -> list[SweepRun]:
    rng = np.random.default_rng(seed)
    runs = []
    t = np.arange(int(1.0 * FS)) / FS
    for f in FEEDS:
        fz = f / (RPM * FLUTES)
        if change_at is not None and slope_jump and f > change_at:
            fz_c = change_at / (RPM * FLUTES)
            fz = fz_c + 2.5 * (fz - fz_c)  # force rises faster past the change (Fig. 8)
        forces = slot_forces(fz, 1.0, rng)
        chatter = 15.0 if (change_at is not None and vib_jump and f > change_at) else 2.0
        forces[:, 0] += chatter * np.sin(2 * np.pi * 1250.0 * t)  # 1250 Hz: no spindle harmonic
        runs.append(SweepRun(float(f), forces, FS, RPM, FLUTES, name=f"F{int(f)}"))
    return runs
