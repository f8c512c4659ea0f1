"""GRBL 1.1h as its firmware answers each line: a model of its source, shared by the dialect
checker (:mod:`planning.nc.dialect`), the simulated GRBL and the GRBL streamer.

GRBL 1.1h, as its source does it (gnea/grbl, ``grbl/protocol.c``, ``gcode.c``, ``report.h``,
``config.h``, ``planner.h``, ``motion_control.c``):

* :func:`grbl_filter` is ``protocol_main_loop``'s character filter: spaces and control characters
  are thrown away, ``(...)`` and ``;`` comments dropped, ``/`` (block delete, "NOT SUPPORTED")
  ignored, lower case upper-cased; a line with more than ``LINE_BUFFER_SIZE - 1`` = 79 characters
  left is answered ``error:11`` (``STATUS_OVERFLOW``, "Line overflow"; ``error:14`` is for EEPROM
  startup lines, not streamed ones). An empty line is answered ``ok``; a ``$`` line is a system
  command; anything else in the Alarm state is ``error:9``.
* :class:`GrblParser` is ``gc_execute_line``'s word import (STEP 2) and error checks (STEP 3) in
  gcode.c's order, with the parser state it keeps (modes, feed, position, offsets), so a line's
  answer is the firmware's: ``error:20`` for what 1.1h does not have (O/A/B/C/D/H/Q words, M6,
  G41/G42, G43 without .1, canned cycles, G98/G99, G90.1, G64, M7 unless compiled in),
  ``error:26`` for ``G2`` without axis words, ``error:22`` for a feed move before any F, ...
  An accepted line also says what executing it does (spindle/coolant/dwell/program-flow
  synchronisation, planner blocks: one per straight move, ``mc_arc``'s segment count per arc).
* Real-time characters (``?`` ``!`` ``~``) are picked off by the serial interrupt wherever they
  stand, comments included: a ``!`` in a comment holds the feed.

The GRBL streamer of ``rig.dnc`` sends :func:`grbl_send_text` of each line (comments, spaces, the N
word and a lone O program number removed: what GRBL discards or does not need) and refuses a
program with any ``error`` problem before the first byte is sent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from planning.nc._grbl_steps import (
    _CCW,
    _CW,
    _LINEAR,
    _NONE,
    _Block,
    _check_block,
    _import_words,
    _read_float,
)

# gcode.c's constants live with its steps; they are this module's names as before
from planning.nc._grbl_steps import GRBL_MAX_LINE_NUMBER as GRBL_MAX_LINE_NUMBER
from planning.nc._grbl_steps import GRBL_MAX_TOOL_NUMBER as GRBL_MAX_TOOL_NUMBER
from planning.nc._grbl_steps import GRBL_N_COORDINATE_SYSTEM as GRBL_N_COORDINATE_SYSTEM
from planning.nc._grbl_steps import MM_PER_INCH as MM_PER_INCH
from planning.nc._grbl_steps import (
    GrblResult as GrblResult,  # re-exported: the simulated GRBL's parse of each line
)
from planning.nc._grbl_steps import (
    GrblState as GrblState,
)

# -- GRBL 1.1h constants (config.h, planner.h, serial.h, gcode.c, defaults.h) -------------------
GRBL_LINE_BUFFER_SIZE = 80  # protocol.h LINE_BUFFER_SIZE
GRBL_LINE_CHARS = GRBL_LINE_BUFFER_SIZE - 1  # protocol.c: char_counter >= LINE_BUFFER_SIZE-1
GRBL_RX_BUFFER_SIZE = 128  # serial.h RX_BUFFER_SIZE (Bf: reports 128 free when empty)
GRBL_BLOCK_BUFFER_SIZE = 16  # planner.h (15 with USE_LINE_NUMBERS)
GRBL_PLANNER_BLOCKS = GRBL_BLOCK_BUFFER_SIZE - 1  # plan_get_block_buffer_available() when empty
GRBL_ARC_TOLERANCE_MM = 0.002  # $12 default (defaults.h DEFAULT_ARC_TOLERANCE)
GRBL_REALTIME = "?!~"  # serial.c ISR: CMD_STATUS_REPORT, CMD_FEED_HOLD, CMD_CYCLE_START

#: error codes (report.h) and their texts (doc/csv/error_codes_en_US.csv)
GRBL_ERRORS: dict[int, str] = {
    1: "expected command letter",
    2: "bad number format",
    3: "invalid statement",
    4: "value < 0",
    5: "setting disabled",
    6: "value < 3 usec",
    7: "EEPROM read fail, using defaults",
    8: "not idle",
    9: "G-code lock (alarm or jog state)",
    10: "homing not enabled",
    11: "line overflow",
    12: "step rate > 30 kHz",
    13: "check door",
    14: "line length exceeded",
    15: "travel exceeded",
    16: "invalid jog command",
    17: "setting disabled (laser mode requires PWM output)",
    20: "unsupported command",
    21: "modal group violation",
    22: "undefined feed rate",
    23: "command value not integer",
    24: "axis command conflict",
    25: "word repeated",
    26: "no axis words",
    27: "invalid line number",
    28: "value word missing",
    29: "unsupported coordinate system",
    30: "G53 invalid motion mode",
    31: "axis words exist",
    32: "no axis words in plane",
    33: "invalid target",
    34: "arc radius error",
    35: "no offsets in plane",
    36: "unused words",
    37: "G43.1 dynamic axis error",
    38: "max value exceeded",
}

#: alarm codes: (name, what happened, what to do) (doc/csv/alarm_codes_en_US.csv, report.h)
GRBL_ALARMS: dict[int, tuple[str, str, str]] = {
    1: ("hard limit", "a hard limit switch was triggered; the machine position is likely lost",
        "clear the switch, soft reset (cutlab dnc reset), then home ($H) before going on"),
    2: ("soft limit", "a G-code target exceeds the machine travel; the position is retained",
        "soft reset (cutlab dnc reset), unlock (cutlab dnc unlock), then fix the program or "
        "the work offset"),
    3: ("abort during cycle", "reset while in motion; the machine position is likely lost",
        "re-home ($H) or, after checking the position, unlock (cutlab dnc unlock)"),
    4: ("probe fail", "the probe was not in the expected initial state",
        "check the probe wiring, then unlock (cutlab dnc unlock)"),
    5: ("probe fail", "the probe did not contact the workpiece within the programmed travel",
        "unlock (cutlab dnc unlock) and probe again"),
    6: ("homing fail", "the homing cycle was reset", "home again ($H)"),
    7: ("homing fail", "the safety door was opened during homing", "close the door, home again"),
    8: ("homing fail", "pull-off travel failed to clear the limit switch",
        "increase the pull-off setting ($27) or check the wiring, home again"),
    9: ("homing fail", "no limit switch found within the search distance",
        "increase the max travel ($130-$132), check the wiring, home again"),
    10: ("homing fail", "the second dual-axis limit switch did not trigger",
         "check the wiring, home again"),
}  # fmt: skip

#: [MSG:...] texts of report_feedback_message (report.c)
GRBL_MSG_RESET_TO_CONTINUE = "[MSG:Reset to continue]"
GRBL_MSG_ALARM_LOCK = "[MSG:'$H'|'$X' to unlock]"
GRBL_MSG_UNLOCKED = "[MSG:Caution: Unlocked]"
GRBL_MSG_PGM_END = "[MSG:Pgm End]"


def grbl_error_text(code: int) -> str:
    return f"error:{code} {GRBL_ERRORS.get(code, 'unknown error')}"


def grbl_alarm_text(code: int) -> str:
    """``ALARM:2 soft limit: ...; do: ...`` (what happened and what to do)."""
    name, what, todo = GRBL_ALARMS.get(code, ("unknown alarm", "see GRBL's alarm list", "reset"))
    return f"ALARM:{code} {name}: {what}; to go on: {todo}"


# -- protocol.c: the line filter -----------------------------------------------------------------
@dataclass(frozen=True)
class GrblLine:
    """A line as ``protocol_main_loop`` hands it on.

    text : the characters kept (upper case, no spaces, comments or ``/``), at most 79
    columns : 1-based source column of each kept character
    overflow : more than 79 characters were left (answered ``error:11``)
    block_delete : a ``/`` was thrown away (GRBL runs the block anyway)
    realtime : (column, char) of ``?`` ``!`` ``~`` anywhere in the line, comments included
    """

    text: str
    columns: tuple[int, ...]
    overflow: bool = False
    block_delete: bool = False
    realtime: tuple[tuple[int, str], ...] = ()


def grbl_filter(raw: str, limit: int = GRBL_LINE_CHARS) -> GrblLine:
    """protocol.c's per-character filter of one line (without its end of line)."""
    out: list[str] = []
    cols: list[int] = []
    paren = semicolon = overflow = delete = False
    rt: list[tuple[int, str]] = []
    for col, c in enumerate(raw, 1):
        if c in GRBL_REALTIME:  # picked off by the serial interrupt, never reach the line
            rt.append((col, c))
            continue
        if paren or semicolon or overflow:
            if c == ")" and paren:
                paren = False
            continue
        if c <= " ":
            continue
        if c == "/":
            delete = True
        elif c == "(":
            paren = True
        elif c == ";":
            semicolon = True
        elif len(out) >= limit:
            overflow = True
        else:
            out.append(c.upper() if "a" <= c <= "z" else c)
            cols.append(col)
    return GrblLine("".join(out), tuple(cols), overflow, delete, tuple(rt))


def grbl_words(text: str) -> list[tuple[str, str, int]] | None:
    """(letter, number text, index) of a filtered line; None if it is not letter+number words."""
    out = []
    i = 0
    while i < len(text):
        c = text[i]
        if not "A" <= c <= "Z":
            return None
        r = _read_float(text, i + 1)
        if r is None:
            return None
        out.append((c, text[i + 1 : r[1]], i))
        i = r[1]
    return out


def grbl_send_text(raw: str) -> str:
    """The line as the streamer sends it to GRBL: what :func:`grbl_filter` keeps (upper case, no
    spaces, comments or real-time characters), without the N word (GRBL needs no line number)
    and without a line holding only an O program number; ``""`` when nothing is left (the line is
    not sent). ``$`` lines are sent as written (stripped of surrounding spaces). ``/`` block
    delete is kept out too: :func:`check_dialect` refuses such lines before anything is sent."""
    s = raw.strip()
    if s.startswith("$"):
        return s
    f = grbl_filter(raw, limit=10**9)
    words = grbl_words(f.text)
    if words is None:
        return f.text
    kept = [(ltr, num) for ltr, num, _ in words if ltr != "N"]
    if len(kept) == 1 and kept[0][0] == "O":
        return ""
    return "".join(ltr + num for ltr, num in kept)


# -- gcode.c: the parser (steps 2 and 3 in planning.nc._grbl_steps) -----------------------------
def _arc_segments(travel_rad: float, radius_mm: float, tol_mm: float) -> int:
    """motion_control.c mc_arc: planner blocks of one arc (segments, or one final line)."""
    if radius_mm <= 0:
        return 1
    seg = math.floor(
        abs(0.5 * travel_rad * radius_mm) / math.sqrt(tol_mm * (2 * radius_mm - tol_mm))
    )
    return max(seg, 1)


class GrblParser:
    """gcode.c's ``gc_execute_line`` error checks and parser state, line by line.

    ``parse(text)`` takes a line as :func:`grbl_filter` leaves it (not a ``$`` line) and returns
    the :class:`GrblResult`; the state changes only when the line is accepted, as in GRBL.
    Not modelled: jogging (``$J=``), probing outcome (G38.x is taken as reaching its target),
    check mode, laser mode, and the EEPROM (work offsets and G28/G30 points start at zero).
    """

    def __init__(self, arc_tolerance_mm: float = GRBL_ARC_TOLERANCE_MM) -> None:
        self.state = GrblState()
        self.arc_tolerance_mm = arc_tolerance_mm

    def reset(self) -> None:
        """Soft reset: gc_init (modes to defaults; position kept as the machine's)."""
        pos = list(self.state.position)
        systems = [list(c) for c in self.state.coord_systems]
        home = [list(h) for h in self.state.home]
        self.state = GrblState(position=pos, coord_systems=systems, home=home)

    def parse(self, line: str) -> GrblResult:
        """GRBL's answer to one line (gcode.c ``gc_execute_line``): import the words (its step 2),
        check the block in gcode.c's order (step 3), then update the parser state (step 4)."""
        b = _Block.of(self.state)
        err = _import_words(b, line) or _check_block(b, self.state)
        if err is not None:
            return err
        return _execute(b, self.state, self.arc_tolerance_mm)

    @staticmethod
    def copy_state(state: GrblState) -> GrblState:
        return GrblState(
            **{
                **state.__dict__,
                "position": list(state.position),
                "coord_offset": list(state.coord_offset),
                "coord_systems": [list(c) for c in state.coord_systems],
                "home": [list(h) for h in state.home],
            }
        )


def _execute(b: _Block, gc: GrblState, arc_tolerance_mm: float) -> GrblResult:
    """Step 4: the parser state after the line (motion is counted in planner blocks, not run)."""
    values, xyz = b.values, b.xyz
    sync = False
    if b.s != gc.spindle_speed and gc.spindle != 0:
        sync = True
    if b.spindle != gc.spindle or b.coolant != gc.coolant:
        sync = True
    gc.inverse_time = b.inverse_time
    gc.feed = b.f
    gc.spindle_speed = b.s
    if "T" in values:
        gc.tool = math.trunc(values["T"])
    gc.spindle, gc.coolant = b.spindle, b.coolant
    dwell = values.get("P", 0.0) if b.non_modal == 4 else 0.0
    gc.plane, gc.inches = b.plane, b.inches
    if b.axis_command == "tlo":
        gc.tool_length_offset = b.tlo_z if b.tool_length == "dynamic" else 0.0
    if b.coord_select != gc.coord_select:
        gc.coord_select = b.coord_select
    gc.incremental = b.incremental
    blocks = 0
    non_modal = b.non_modal
    if non_modal == 10 and b.g10 is not None:
        sel, data = b.g10
        gc.coord_systems[sel] = data
    elif non_modal in (28, 30):
        if b.axis_command:
            blocks += xyz != gc.position
        blocks += b.ijk != (xyz if b.axis_command else gc.position)
        gc.position = list(b.ijk)
    elif non_modal == 281:
        gc.home[0] = list(gc.position)
    elif non_modal == 301:
        gc.home[1] = list(gc.position)
    elif non_modal == 92 and b.new_g92 is not None:
        gc.coord_offset = b.new_g92
    elif non_modal == 921:
        gc.coord_offset = [0.0, 0.0, 0.0]
    gc.motion = b.motion
    if b.motion != _NONE and b.axis_command == "motion":
        if b.motion in (_CW, _CCW):
            blocks += _arc_segments(b.arc_travel, b.arc_radius, arc_tolerance_mm)
        else:
            blocks += xyz != gc.position
        gc.position = list(xyz)
    if b.program_flow == "end":
        gc.motion, gc.plane, gc.incremental, gc.inverse_time = _LINEAR, 0, False, False
        gc.coord_select, gc.spindle, gc.coolant = 0, 0, 0
    sync = sync or non_modal == 4 or bool(b.program_flow)
    return GrblResult(0, sync=sync, dwell_s=dwell, planner_blocks=int(blocks),
                      program_flow=b.program_flow, line_number=int(values.get("N", 0)))  # fmt: skip
