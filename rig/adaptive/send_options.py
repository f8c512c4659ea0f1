"""`dnc send --adaptive` checked before anything is opened: the loop needs a real-time override
on the serial line (GRBL 1.1's 0x90-0x9D bytes), its force target, hard limit and the spindle's
speed."""

from __future__ import annotations

from rig.adaptive.override import refusal
from rig.dnc import DncError, dnc_machine

__all__ = ["check_send_adaptive"]


def check_send_adaptive(
    mode: str, protocol: str, machine: str | None, target_force_n: float | None,
    max_force_n: float | None, spindle_rpm: float | None,
) -> None:  # fmt: skip
    """Refuse ``--adaptive MODE`` for a controller without a real-time override (a Fanuc drip
    feed: its override is the panel's dial, or an external input, the machine config's
    ``override``), or without --target-force, --max-force and --spindle-rpm."""
    protocol, m = dnc_machine(protocol, machine)
    why = refusal(m, protocol)
    if why is not None:
        raise DncError(f"dnc send --adaptive {mode}: {why} (--protocol grbl)")
    # GRBL: the loop (rig.adaptive.send) needs its target, hard limit and the spindle's speed
    for opt, val in (("--target-force", target_force_n), ("--max-force", max_force_n),
                     ("--spindle-rpm", spindle_rpm)):  # fmt: skip
        if val is None:
            raise DncError(f"dnc send --adaptive {mode}: {opt} is required (N, N, rpm)")
    assert target_force_n is not None and max_force_n is not None
    if not target_force_n < max_force_n:
        raise DncError(f"dnc send --adaptive: --target-force {target_force_n:g} N: expected "
                       f"below --max-force {max_force_n:g} N")  # fmt: skip
