"""A simulated controller as ``cutlab dnc sim-controller`` runs it: built from fault knobs given as
``KNOB=VALUE`` text, run on its pseudo-terminal until a duration, SIGTERM or Ctrl-C, and summed
up in a dict.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, NotRequired, TypedDict

from rig.dnc import DncError
from rig.dnc.protocols import protocol_of
from rig.sim.clock import SimClock
from rig.sim.fanuc import SimFanuc
from rig.sim.grbl import SimGrbl

if TYPE_CHECKING:
    from analysis.config import MachineConfig

#: A fault knob's value: a number (a ``*_s`` knob's first one in s) or two (k, code)
KnobValue = int | float | tuple[int | float, ...]


class ControllerSummary(TypedDict):
    """What a simulated controller received and did (`cutlab dnc sim-controller`): the common
    figures, then a Fanuc's flow control or a GRBL's planner, errors and state."""

    path: str
    bytes_received: int
    sha256: str
    blocks_executed: int
    last_completed_block: int
    starved_fraction: float
    overruns: int
    framing_errors: int
    alarm: str
    xoff_count: NotRequired[int]
    max_chars_after_xoff: NotRequired[int]
    planner_full_waits: NotRequired[int]
    errors: NotRequired[int]
    oks: NotRequired[int]
    state: NotRequired[str]


#: each simulated controller, by the protocol it speaks
_CLASSES: dict[str, type[SimFanuc] | type[SimGrbl]] = {c.protocol: c for c in (SimFanuc, SimGrbl)}


def controller_class(protocol: str) -> type[SimFanuc] | type[SimGrbl]:
    """The simulated controller of ``protocol`` (a dialect without one: see
    :func:`rig.dnc.protocols.protocol_of`)."""
    return _CLASSES[protocol_of(protocol).name]


def parse_knobs(items: Sequence[str]) -> dict[str, KnobValue]:
    """``["alarm_at_block=50,2", "stop_answering_at_s=3"]`` -> ``{"sim_alarm_at_block": (50, 2),
    "sim_stop_answering_at_s": 3.0}``: ints, the first number of a ``*_s`` knob a float (s)."""
    out: dict[str, KnobValue] = {}
    for it in items:
        key, sep, val = it.partition("=")
        key = key.strip().removeprefix("sim_")
        if not sep or not val:
            raise DncError(f"--sim {it!r}: expected KNOB=VALUE, e.g. alarm_at_block=50,2")
        try:
            nums = tuple(float(v) if key.endswith("_s") and i == 0 else int(v)
                         for i, v in enumerate(val.split(",")))  # fmt: skip
        except ValueError:
            raise DncError(f"--sim {it!r}: value must be a number or two (k,code)") from None
        out[f"sim_{key}"] = nums[0] if len(nums) == 1 else nums
    return out


def valid_knobs(protocol: str) -> list[str]:
    """The fault knobs of the ``protocol`` controller: the ``sim_*`` keyword parameters of its
    ``__init__`` and its bases', without the prefix."""
    return sorted(
        {
            name.removeprefix("sim_")
            for klass in _CLASSES[protocol].__mro__
            if "__init__" in vars(klass)
            for name in inspect.signature(vars(klass)["__init__"]).parameters
            if name.startswith("sim_")
        }
    )


def sim_controller(
    protocol: str,
    machine: MachineConfig,
    *,
    speed: float = 1.0,
    baud: int | None = None,
    knobs: Sequence[str] = (),
) -> SimFanuc | SimGrbl:
    """The simulated ``protocol`` controller of ``machine`` at ``speed`` simulated s per wall s
    and ``baud`` (None: the machine's serial.baudrate), with the fault ``knobs`` (KNOB=VALUE
    text, see :func:`parse_knobs`); a Fanuc takes the machine's character framing."""
    kw: dict[str, Any] = dict(parse_knobs(knobs))  # the controller's keywords, of many types
    valid = valid_knobs(protocol)
    bad = [k.removeprefix("sim_") for k in kw if k.removeprefix("sim_") not in valid]
    if bad:
        raise DncError(
            f"--sim {bad[0]}: unknown knob for the {protocol} controller; valid knobs: "
            + ", ".join(valid)
        )
    if not speed > 0:
        raise DncError(f"--speed = {speed}: must be > 0 (simulated s per wall s)")
    kw |= {"clock": SimClock(speed), "baudrate": baud or machine.serial.baudrate}
    if not protocol_of(protocol).serial_8n1_only:  # a tape reader takes the machine's framing
        s = machine.serial
        kw |= {"bytesize": s.bytesize, "parity": s.parity, "stopbits": s.stopbits,
               "flow_control": s.flow_control}  # fmt: skip
    try:
        return _CLASSES[protocol](machine, **kw)
    except TypeError as exc:  # a knob of the right name but an unusable value
        raise DncError(f"--sim: the {protocol} controller refused the knobs ({exc})") from None


def controller_summary(ctl: SimFanuc | SimGrbl) -> ControllerSummary:
    """What the controller received and did: bytes, SHA-256, blocks, alarms, flow control."""
    out: ControllerSummary = {
        "path": ctl.path,
        "bytes_received": len(ctl.received),
        "sha256": ctl.received_sha256(),
        "blocks_executed": len(ctl.executed),
        "last_completed_block": ctl.last_completed_block,
        "starved_fraction": ctl.starved_fraction,
        "overruns": ctl.overruns,
        "framing_errors": ctl.framing_errors,
        "alarm": ctl.alarm,
    }
    if isinstance(ctl, SimFanuc):
        out["xoff_count"] = ctl.xoff_count
        out["max_chars_after_xoff"] = ctl.max_after_xoff
        return out
    out["planner_full_waits"] = ctl.planner_waits
    out["errors"] = len(ctl.errors)
    out["oks"] = ctl.oks
    out["state"] = ctl.state_name()
    return out


def run_controller(
    ctl: SimFanuc | SimGrbl,
    duration_s: float | None = None,
    on_started: Callable[[str], None] | None = None,
) -> ControllerSummary:
    """Run ``ctl`` on its pseudo-terminal for ``duration_s`` wall s (None: until SIGTERM or
    Ctrl-C), calling ``on_started(path)`` once the path exists; returns
    :func:`controller_summary`. Call it from the main thread (it handles SIGTERM)."""
    import signal
    import threading

    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())  # before the path is out: a script
    path = ctl.start()  # may stop us as soon as it has read it
    if on_started is not None:
        on_started(path)
    try:
        stop.wait(duration_s)
    except KeyboardInterrupt:
        pass
    finally:
        ctl.stop()
    summary = controller_summary(ctl)
    summary["path"] = path
    return summary
