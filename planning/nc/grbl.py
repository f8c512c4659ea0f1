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
from dataclasses import dataclass, field

# -- GRBL 1.1h constants (config.h, planner.h, serial.h, gcode.c, defaults.h) -------------------
GRBL_LINE_BUFFER_SIZE = 80  # protocol.h LINE_BUFFER_SIZE
GRBL_LINE_CHARS = GRBL_LINE_BUFFER_SIZE - 1  # protocol.c: char_counter >= LINE_BUFFER_SIZE-1
GRBL_RX_BUFFER_SIZE = 128  # serial.h RX_BUFFER_SIZE (Bf: reports 128 free when empty)
GRBL_BLOCK_BUFFER_SIZE = 16  # planner.h (15 with USE_LINE_NUMBERS)
GRBL_PLANNER_BLOCKS = GRBL_BLOCK_BUFFER_SIZE - 1  # plan_get_block_buffer_available() when empty
GRBL_MAX_LINE_NUMBER = 10_000_000  # gcode.c MAX_LINE_NUMBER
GRBL_MAX_TOOL_NUMBER = 255  # gcode.c MAX_TOOL_NUMBER
GRBL_N_COORDINATE_SYSTEM = 6  # G54..G59
GRBL_ARC_TOLERANCE_MM = 0.002  # $12 default (defaults.h DEFAULT_ARC_TOLERANCE)
GRBL_REALTIME = "?!~"  # serial.c ISR: CMD_STATUS_REPORT, CMD_FEED_HOLD, CMD_CYCLE_START
MM_PER_INCH = 25.4

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


def _read_float(s: str, i: int) -> tuple[float, int] | None:
    """nuts_bolts.c read_float: sign, digits with at most one '.', no exponent; None if no
    digit. Returns (value, index after the number)."""
    n = len(s)
    j = i
    neg = False
    if j < n and s[j] in "+-":
        neg = s[j] == "-"
        j += 1
    digits = 0
    dot = False
    start = j
    while j < n:
        c = s[j]
        if "0" <= c <= "9":
            digits += 1
        elif c == "." and not dot:
            dot = True
        else:
            break
        j += 1
    if not digits:
        return None
    v = float(s[start:j]) if s[start:j] not in (".",) else 0.0
    return (-v if neg else v), j


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


# -- gcode.c: the parser -------------------------------------------------------------------------
# motion modes (gcode.h): G0 0, G1 1, G2 2, G3 3, G38.x 140.., G80 80
_SEEK, _LINEAR, _CW, _CCW, _NONE = 0, 1, 2, 3, 80
_AXES = "XYZ"


@dataclass
class GrblState:
    """gc_state: what a line inherits (positions mm, machine frame as GRBL keeps them)."""

    motion: int = _SEEK
    plane: int = 0  # 0 XY, 1 ZX, 2 YZ
    inches: bool = False
    incremental: bool = False
    inverse_time: bool = False
    coord_select: int = 0  # 0 = G54
    spindle: int = 0  # 0 off, 1 cw, -1 ccw
    coolant: int = 0  # bit 1 flood (M8)
    feed: float = 0.0  # mm/min (0: undefined)
    spindle_speed: float = 0.0
    tool: int = 0
    tool_length_offset: float = 0.0
    position: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    coord_offset: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])  # G92
    coord_systems: list[list[float]] = field(
        default_factory=lambda: [[0.0, 0.0, 0.0] for _ in range(GRBL_N_COORDINATE_SYSTEM)]
    )
    home: list[list[float]] = field(default_factory=lambda: [[0.0] * 3, [0.0] * 3])  # G28, G30


@dataclass(frozen=True)
class GrblResult:
    """GRBL's answer to one line and, when ``ok``, what executing it involves.

    code : 0 (``ok``) or the error number; word, index : the offending word of the filtered line
    sync : the line waits for the planner to empty before it runs (spindle, coolant, dwell,
        program pause/end: ``protocol_buffer_synchronize``)
    dwell_s : G4 P, s; planner_blocks : blocks the line puts in the planner
    program_flow : "", "pause" (M0) or "end" (M2/M30)
    """

    code: int
    word: str = ""
    index: int = -1
    sync: bool = False
    dwell_s: float = 0.0
    planner_blocks: int = 0
    program_flow: str = ""
    line_number: int = 0

    @property
    def ok(self) -> bool:
        return self.code == 0


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


# -- gcode.c gc_execute_line, in its steps -------------------------------------------------------
@dataclass
class _Block:
    """One line's words and the modal values it sets (gcode.c's gc_block), from the state."""

    motion: int
    plane: int
    inches: bool
    incremental: bool
    inverse_time: bool
    coord_select: int
    spindle: int
    coolant: int
    words: list[tuple[str, str, int]] = field(default_factory=list)
    program_flow: str = ""
    non_modal: int = 0  # 0 none; 4, 10, 28, 30, 53, 92 (+ .1 as 281, 301, 921)
    tool_length: str | None = None
    axis_command: str = ""  # "", "non_modal", "motion", "tlo"
    groups: set[str] = field(default_factory=set)
    values: dict[str, float] = field(default_factory=dict)
    widx: dict[str, int] = field(default_factory=dict)
    k_cmd: int = 0  # the word an error about the whole block points at (its G command)
    # step 3's results
    used: dict[str, float] = field(default_factory=dict)  # value words still unused
    axis_words: list[str] = field(default_factory=list)
    f: float = 0.0
    s: float = 0.0
    xyz: list[float] = field(default_factory=list)
    tlo_z: float = 0.0
    ijk: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    new_g92: list[float] | None = None
    g10: tuple[int, list[float]] | None = None
    arc_travel: float = 0.0
    arc_radius: float = 0.0

    @classmethod
    def of(cls, gc: GrblState) -> _Block:
        return cls(gc.motion, gc.plane, gc.inches, gc.incremental, gc.inverse_time,
                   gc.coord_select, gc.spindle, gc.coolant)  # fmt: skip

    def fail(self, code: int, k: int) -> GrblResult:
        w = self.words[k] if 0 <= k < len(self.words) else ("", "", -1)
        return GrblResult(code, w[0] + w[1], w[2])

    def fail_word(self, code: int, letter: str) -> GrblResult:
        return self.fail(code, self.widx.get(letter, self.k_cmd))

    @property
    def unit(self) -> float:
        return MM_PER_INCH if self.inches else 1.0


def _import_words(b: _Block, line: str) -> GrblResult | None:
    """Step 2: the words, each checked as gcode.c reads it."""
    i, n = 0, len(line)
    while i < n:
        letter = line[i]
        if not "A" <= letter <= "Z":
            return GrblResult(1, line[i], i)
        r = _read_float(line, i + 1)
        if r is None:
            return GrblResult(2, letter, i)
        value, j = r
        b.words.append((letter, line[i + 1 : j], i))
        k = len(b.words) - 1
        i = j
        int_value = math.trunc(value)
        mantissa = round(100 * (value - int_value))
        if letter in "GM":
            int_value &= 0xFF  # uint8_t int_value in gcode.c
        if letter == "G":
            err = _g_word(b, k, int_value, mantissa)
        elif letter == "M":
            err = _m_word(b, k, int_value, mantissa)
        else:
            err = _value_word(b, k, letter, value)
        if err is not None:
            return err
    b.used = dict(b.values)  # value words still unused (gcode.c value_words)
    return None


def _g_word(b: _Block, k: int, int_value: int, mantissa: int) -> GrblResult | None:
    if int_value in (10, 28, 30, 92) and mantissa == 0:
        if b.axis_command:
            return b.fail(24, k)
        b.axis_command = "non_modal"
    if int_value in (10, 28, 30, 92, 4, 53):
        group = "G0"
        b.k_cmd = k
        b.non_modal = int_value
        if int_value in (28, 30, 92):
            if mantissa not in (0, 10):
                return b.fail(20, k)
            b.non_modal = int_value * 10 + mantissa // 10 if mantissa else int_value
            mantissa = 0
    elif int_value in (0, 1, 2, 3, 38, 80):
        if int_value != 80:
            if b.axis_command:
                return b.fail(24, k)
            b.axis_command = "motion"
        group = "G1"
        b.k_cmd = k
        b.motion = int_value
        if int_value == 38:
            if mantissa not in (20, 30, 40, 50):
                return b.fail(20, k)
            b.motion = 100 + int_value + mantissa // 10
            mantissa = 0
    elif int_value in (17, 18, 19):
        group, b.plane = "G2", int_value - 17
    elif int_value in (90, 91):
        if mantissa == 0:
            group, b.incremental = "G3", int_value == 91
        else:
            group = "G4"
            if mantissa != 10 or int_value == 90:
                return b.fail(20, k)  # G90.1 not supported
            mantissa = 0
    elif int_value in (93, 94):
        group, b.inverse_time = "G5", int_value == 93
    elif int_value in (20, 21):
        group, b.inches = "G6", int_value == 20
    elif int_value == 40:
        group = "G7"
    elif int_value in (43, 49):
        group = "G8"
        if b.axis_command:
            return b.fail(24, k)
        b.axis_command = "tlo"
        if int_value == 49:
            b.tool_length = "cancel"
        elif mantissa == 10:
            b.tool_length = "dynamic"
        else:
            return b.fail(20, k)  # G43 without .1
        mantissa = 0
    elif 54 <= int_value <= 59:
        group, b.coord_select = "G12", int_value - 54
    elif int_value == 61:
        group = "G13"
        if mantissa != 0:
            return b.fail(20, k)
    else:
        return b.fail(20, k)
    if mantissa > 0:
        return b.fail(23, k)
    return _group(b, group, k)


def _group(b: _Block, group: str, k: int) -> GrblResult | None:
    if group in b.groups:
        return b.fail(21, k)
    b.groups.add(group)
    return None


def _m_word(b: _Block, k: int, int_value: int, mantissa: int) -> GrblResult | None:
    if mantissa > 0:
        return b.fail(23, k)
    if int_value in (0, 1, 2, 30):
        group = "M4"
        if int_value == 0:
            b.program_flow = "pause"
        elif int_value in (2, 30):
            b.program_flow = "end"
    elif int_value in (3, 4, 5):
        group = "M7"
        b.spindle = {3: 1, 4: -1, 5: 0}[int_value]
    elif int_value in (8, 9):  # M7 only with ENABLE_M7 (off by default)
        group = "M8"
        b.coolant = 2 if int_value == 8 else 0
    else:
        return b.fail(20, k)  # M6 and the rest
    return _group(b, group, k)


def _value_word(b: _Block, k: int, letter: str, value: float) -> GrblResult | None:
    if letter not in "FIJKLNPRSTXYZ":
        return b.fail(20, k)  # A B C D E H O Q U V W ...
    if letter in b.values:
        return b.fail(25, k)
    if letter in "FNPTS" and value < 0:
        return b.fail(4, k)
    if letter == "T" and value > GRBL_MAX_TOOL_NUMBER:
        return b.fail(38, k)
    b.values[letter] = value
    b.widx[letter] = k
    return None


def _check_block(b: _Block, gc: GrblState) -> GrblResult | None:
    """Step 3: the error checks, in gcode.c's order."""
    values = b.values
    b.axis_words = [a for a in _AXES if a in values]
    if b.axis_words and not b.axis_command:
        b.axis_command = "motion"
    if "N" in values and values["N"] > GRBL_MAX_LINE_NUMBER:
        return b.fail_word(27, "N")
    b.f = values.get("F", 0.0)
    if b.inverse_time:
        if (b.axis_command == "motion" and b.motion not in (_NONE, _SEEK)
                and "F" not in values):  # fmt: skip
            return b.fail(22, b.k_cmd)
    elif not gc.inverse_time:
        if "F" in values:
            b.f = b.f * MM_PER_INCH if b.inches else b.f
        else:
            b.f = gc.feed
    b.s = values.get("S", gc.spindle_speed)
    if b.non_modal == 4:
        if "P" not in values:
            return b.fail(28, b.k_cmd)
        b.used.pop("P", None)
    b.xyz = [values.get(a, 0.0) * b.unit for a in _AXES]
    b.tlo_z = b.xyz[2]
    if b.axis_command == "tlo" and b.tool_length == "dynamic" and b.axis_words != ["Z"]:
        return b.fail(37, b.k_cmd)
    err = _check_non_modal(b, gc) or _check_motion(b, gc)
    if err is not None:
        return err
    for w in "NFST":
        b.used.pop(w, None)
    if b.axis_command:
        for w in _AXES:
            b.used.pop(w, None)
    if b.used:
        first = min(b.used, key=lambda w: b.widx[w])
        return b.fail_word(36, first)
    return None


def _check_non_modal(b: _Block, gc: GrblState) -> GrblResult | None:
    """G10, G92, and the targets of the others (G28/G30: through their points; G53)."""
    values, xyz = b.values, b.xyz
    block_coord = list(gc.coord_systems[b.coord_select])
    if b.non_modal == 10:
        return _check_g10(b, gc)
    if b.non_modal == 92:
        if not b.axis_words:
            return b.fail(26, b.k_cmd)
        b.new_g92 = [
            (gc.position[ax] - block_coord[ax] - xyz[ax]
             - (gc.tool_length_offset if ax == 2 else 0.0))
            if _AXES[ax] in values else gc.coord_offset[ax]
            for ax in range(3)
        ]  # fmt: skip
        return None
    if b.axis_command != "tlo" and b.axis_words:
        for ax in range(3):
            if _AXES[ax] not in values:
                xyz[ax] = gc.position[ax]
            elif b.non_modal != 53:
                if not b.incremental:
                    xyz[ax] += block_coord[ax] + gc.coord_offset[ax]
                    if ax == 2:
                        xyz[ax] += gc.tool_length_offset
                else:
                    xyz[ax] += gc.position[ax]
    if b.non_modal in (28, 30):
        home = list(gc.home[0 if b.non_modal == 28 else 1])
        if b.axis_words:
            for ax in range(3):
                if _AXES[ax] not in values:
                    home[ax] = gc.position[ax]
        else:
            b.axis_command = ""
        b.ijk = home
    elif b.non_modal == 53 and b.motion not in (_SEEK, _LINEAR):
        return b.fail(30, b.k_cmd)
    return None


def _check_g10(b: _Block, gc: GrblState) -> GrblResult | None:
    values = b.values
    if not b.axis_words:
        return b.fail(26, b.k_cmd)
    if "P" not in values and "L" not in values:
        return b.fail(28, b.k_cmd)
    p = math.trunc(values.get("P", 0.0))
    if p > GRBL_N_COORDINATE_SYSTEM:
        return b.fail_word(29, "P")
    L = math.trunc(values.get("L", 0.0)) & 0xFF
    if L != 20:
        if L == 2:
            if "R" in values:
                return b.fail_word(20, "R")
        else:
            return b.fail_word(20, "L")
    b.used.pop("L", None)
    b.used.pop("P", None)
    sel = p - 1 if p > 0 else b.coord_select
    data = list(gc.coord_systems[sel])
    for ax in range(3):
        if _AXES[ax] in values:
            if L == 20:
                data[ax] = gc.position[ax] - gc.coord_offset[ax] - b.xyz[ax]
                if ax == 2:
                    data[ax] -= gc.tool_length_offset
            else:
                data[ax] = b.xyz[ax]
    b.g10 = (sel, data)
    return None


def _check_motion(b: _Block, gc: GrblState) -> GrblResult | None:
    """The motion mode's checks (G80 with axis words, feed, arcs, probing)."""
    if b.motion == _NONE:
        if b.axis_words:
            return b.fail_word(31, b.axis_words[0])
        return None
    if b.axis_command != "motion":
        return None
    if b.motion == _SEEK:
        if not b.axis_words:
            b.axis_command = ""
        return None
    if b.f == 0.0:
        return b.fail(22, b.k_cmd)
    if b.motion == _LINEAR:
        if not b.axis_words:
            b.axis_command = ""
    elif b.motion in (_CW, _CCW):
        return _check_arc(b, gc)
    elif b.motion >= 100:  # G38.x probing
        if not b.axis_words:
            return b.fail(26, b.k_cmd)
        if b.xyz == gc.position:
            return b.fail(33, b.k_cmd)
    return None


def _check_arc(b: _Block, gc: GrblState) -> GrblResult | None:
    """G2/G3: the centre from R or I J K, its radius error, and mc_arc's angular travel."""
    values, xyz, ijk = b.values, b.xyz, b.ijk
    a0, a1, _ = {0: (0, 1, 2), 1: (2, 0, 1), 2: (1, 2, 0)}[b.plane]
    if not b.axis_words:
        return b.fail(26, b.k_cmd)
    if _AXES[a0] not in values and _AXES[a1] not in values:
        return b.fail_word(32, b.axis_words[0])
    x = xyz[a0] - gc.position[a0]
    y = xyz[a1] - gc.position[a1]
    if "R" in values:
        b.used.pop("R")
        if xyz == gc.position:
            return b.fail_word(33, "R")
        r = values["R"] * b.unit
        h = 4.0 * r * r - x * x - y * y
        if h < 0:
            return b.fail_word(34, "R")
        h = -math.sqrt(h) / math.hypot(x, y)
        if b.motion == _CCW:
            h = -h
        if r < 0:
            h, r = -h, -r
        ijk[a0] = 0.5 * (x - y * h)
        ijk[a1] = 0.5 * (y + x * h)
        b.arc_radius = r
    else:
        off = {"X": "I", "Y": "J", "Z": "K"}
        if off[_AXES[a0]] not in values and off[_AXES[a1]] not in values:
            return b.fail(35, b.k_cmd)
        for w in "IJK":
            b.used.pop(w, None)
        for ax, w in enumerate("IJK"):
            ijk[ax] = values.get(w, 0.0) * b.unit
        x -= ijk[a0]
        y -= ijk[a1]
        target_r = math.hypot(x, y)
        b.arc_radius = math.hypot(ijk[a0], ijk[a1])
        delta_r = abs(target_r - b.arc_radius)
        if delta_r > 0.005 and (delta_r > 0.5 or delta_r > 0.001 * b.arc_radius):
            return b.fail(33, b.k_cmd)
    # mc_arc's angular travel
    ra0, ra1 = -ijk[a0], -ijk[a1]
    rt0 = xyz[a0] - (gc.position[a0] + ijk[a0])
    rt1 = xyz[a1] - (gc.position[a1] + ijk[a1])
    t = math.atan2(ra0 * rt1 - ra1 * rt0, ra0 * rt0 + ra1 * rt1)
    eps = 5e-7  # ARC_ANGULAR_TRAVEL_EPSILON
    if b.motion == _CW:
        t = t - 2 * math.pi if t >= -eps else t
    else:
        t = t + 2 * math.pi if t <= eps else t
    b.arc_travel = t
    return None


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
