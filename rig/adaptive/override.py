"""How the loop's overrides reach the controller (issue 29 item 5), and the one-line refusal when
they cannot: GRBL 1.1 takes real-time bytes on its serial line (0x90-0x9D); a Fanuc drip feed has
none (its override is the panel's dial, or a PMC input a lab may wire to a DAQ's analog output:
the machine config's ``override = "external-analog"``). cutlab drives no analog override output
yet, so that path is declared but refused too, naming why, rather than a loop that sends nothing.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rig.dnc.protocols import protocol_of

if TYPE_CHECKING:
    from analysis.config import MachineConfig

#: the override paths the loop can drive
DRIVEN = ("grbl-realtime",)


def override_path(machine: MachineConfig, protocol: str) -> str:
    """The path for ``machine`` streamed as ``protocol``: a GRBL stream is GRBL's real-time
    bytes (the twin's ``[sim] protocol = "grbl"`` included); otherwise the machine config's
    ``override`` (by dialect when unset)."""
    if protocol_of(protocol).realtime_bytes:
        return "grbl-realtime"
    path = getattr(machine, "override_path", None)
    return path if path is not None else "none"


def refusal(machine: MachineConfig, protocol: str) -> str | None:
    """None when the loop can drive the override; else the one line saying why not."""
    path = override_path(machine, protocol)
    if path in DRIVEN:
        return None
    name = getattr(machine, "name", "?")
    if path == "external-analog":
        return (f'the {protocol} controller of machine {name!r} takes its override on an external '
                'input (override = "external-analog"), and cutlab drives no analog override '
                "output yet: nothing would reach the controller")  # fmt: skip
    return (f"the {protocol} controller of machine {name!r} has no override path (override = "
            f'"{path}": a drip feed has no real-time override over serial); expected GRBL 1.1 '
            '(override = "grbl-realtime") or an external override input')  # fmt: skip
