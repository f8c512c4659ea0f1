"""The streaming protocols (rig.dnc.protocols): each agrees with its dialect, its streamer, its
simulated controller and its default machine, and the rules rig asks of it act as the controls
do (GRBL refuses compensation and the codes the preamble drops; a Fanuc's G82 P is in ms)."""

from __future__ import annotations

import pytest

from analysis.config import DIALECT_NAMES, REALTIME_OVERRIDE_DIALECTS, load_machine
from planning.nc import DWELL, interpret
from planning.nc.dialects import get, protocols
from rig.dnc import (
    DncError,
    StreamProtocol,
    program_from_text,
    protocol_of,
    restart_plan,
    streamer_class,
)
from rig.dnc.port import PROTOCOLS
from rig.dnc.protocols import FALLBACK, REGISTRY
from rig.sim import controller_class

ALL = list(REGISTRY.values())


def test_the_registry_is_the_dialects_protocols() -> None:
    assert tuple(REGISTRY) == protocols() == PROTOCOLS
    for p in ALL:
        assert get(p.dialect_name).protocol == p.name  # the dialect names its protocol back
        assert p.dialect is get(p.dialect_name)


@pytest.mark.parametrize("p", ALL, ids=lambda p: p.name)
def test_streamer_controller_and_machine_speak_the_protocol(p: StreamProtocol) -> None:
    assert streamer_class(p.name).protocol == p.name
    assert controller_class(p.name).protocol == p.name
    assert load_machine(p.default_machine).dialect == p.dialect_name
    assert protocol_of(p) is p and protocol_of(p.name) is p


def test_a_dialect_without_a_protocol_is_fed_as_a_tape_reader() -> None:
    for name in DIALECT_NAMES:
        own = get(name).protocol
        assert protocol_of(name) is (REGISTRY[own] if own else FALLBACK)
    assert not FALLBACK.paced_by_ok and not FALLBACK.realtime_bytes


def test_an_unknown_protocol_is_one_line_naming_the_known_ones() -> None:
    with pytest.raises(DncError) as exc:
        protocol_of("heidenhain")
    msg = str(exc.value)
    assert "\n" not in msg and "'heidenhain'" in msg and "fanuc, grbl" in msg


def test_the_machine_configs_override_default_follows_the_protocols() -> None:
    """analysis.config cannot import rig: its REALTIME_OVERRIDE_DIALECTS is data, checked here."""
    assert REALTIME_OVERRIDE_DIALECTS == tuple(
        n for n in DIALECT_NAMES if protocol_of(n).realtime_bytes
    )


def test_rules_that_go_together() -> None:
    for p in ALL:
        # an ok-paced control acknowledges lines; a drip feed only knows what was sent
        assert p.done == ("acknowledged" if p.paced_by_ok else "fully sent")
        # real-time bytes and status reports are one serial protocol (GRBL's)
        assert p.realtime_bytes == p.status_query == p.end_known
        assert (p.bauds is None) == p.serial_8n1_only


COMPENSATED = """G21 G90 G17 G94
G0 X0 Y0 Z5
G1 Z-1 F200
G41 D1 G1 X10 Y0
G1 X20
G1 X30
G40 G1 X40
M30
"""


def test_restart_with_compensation_in_force_is_refused_where_the_dialect_has_none() -> None:
    prog = program_from_text(COMPENSATED, "comp.nc")
    with pytest.raises(DncError, match="G41/G49 compensation, which GRBL does not take"):
        restart_plan(prog, 5, "grbl")
    assert "G41" in " ".join(restart_plan(prog, 5, "fanuc").preamble)


CYCLE = """G21 G90 G17 G94
G54
S1000 M3
G0 X0 Y0 Z10
G98 G82 X5 Y5 Z-3 R2 P500 F100
X10 Y5
X15 Y5
G80
M30
"""


def test_a_restarted_g82_dwells_as_long_in_the_protocols_dialect() -> None:
    """Fanuc's G82 P is in ms (P500: 0.5 s): the completed hole block says so, and interpreted
    in Fanuc's dialect the restarted holes dwell 0.5 s as the original ones did."""
    plan = restart_plan(program_from_text(CYCLE, "g82.nc"), 5, "fanuc")
    (text,) = plan.replaced.values()
    assert "P500" in text.split()
    rest = CYCLE.splitlines()[6:]
    again = interpret("\n".join([*plan.preamble, text, *rest]) + "\n", dialect="fanuc")
    whole = interpret(CYCLE, dialect="fanuc")
    assert list(whole.dwell_s[whole.kind == DWELL]) == [0.5, 0.5, 0.5]
    assert list(again.dwell_s[again.kind == DWELL]) == [0.5, 0.5]


def test_the_grbl_preamble_leaves_out_what_grbl_refuses() -> None:
    text = "G21 G90 G17 G98\nT1 M6\nS1000 M3\nG0 X0 Y0 Z5\nG1 Z-1 F200\nG1 X10\nG1 X20\nM30\n"
    prog = program_from_text(text, "t.nc")
    fanuc = " ".join(restart_plan(prog, 6, "fanuc").preamble).split()
    grbl = " ".join(restart_plan(prog, 6, "grbl").preamble).split()
    assert "M6" in fanuc and "G98" in fanuc
    assert not {"M6", "G98", "G99", "G90.1"} & set(grbl)
    interpret("\n".join(restart_plan(prog, 6, "grbl").preamble) + "\n", dialect="grbl")
