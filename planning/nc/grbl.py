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

    def parse(self, line: str) -> GrblResult:  # noqa: C901 - gcode.c's one long function
        gc = self.state
        words = []
        i = 0
        n = len(line)
        # ---- STEP 2: import the words
        motion = gc.motion
        plane, inches, incremental = gc.plane, gc.inches, gc.incremental
        inverse_time = gc.inverse_time
        coord_select = gc.coord_select
        spindle, coolant = gc.spindle, gc.coolant
        program_flow = ""
        non_modal = 0  # 0 none; 4, 10, 28, 30, 53, 92 (+ .1 as 281, 301, 921)
        tool_length: str | None = None
        axis_command = ""  # "", "non_modal", "motion", "tlo"
        groups: set[str] = set()
        values: dict[str, float] = {}
        widx: dict[str, int] = {}
        k_cmd = 0  # the word an error about the whole block points at (its G command)

        def fail(code: int, k: int) -> GrblResult:
            w = words[k] if 0 <= k < len(words) else ("", "", -1)
            return GrblResult(code, w[0] + w[1], w[2])

        while i < n:
            letter = line[i]
            if not "A" <= letter <= "Z":
                return GrblResult(1, line[i], i)
            r = _read_float(line, i + 1)
            if r is None:
                return GrblResult(2, letter, i)
            value, j = r
            words.append((letter, line[i + 1 : j], i))
            k = len(words) - 1
            i = j
            int_value = math.trunc(value)
            mantissa = round(100 * (value - int_value))
            if letter in "GM":
                int_value &= 0xFF  # uint8_t int_value in gcode.c
            if letter == "G":
                if int_value in (10, 28, 30, 92) and mantissa == 0:
                    if axis_command:
                        return fail(24, k)
                    axis_command = "non_modal"
                if int_value in (10, 28, 30, 92, 4, 53):
                    group = "G0"
                    k_cmd = k
                    non_modal = int_value
                    if int_value in (28, 30, 92):
                        if mantissa not in (0, 10):
                            return fail(20, k)
                        non_modal = int_value * 10 + mantissa // 10 if mantissa else int_value
                        mantissa = 0
                elif int_value in (0, 1, 2, 3, 38, 80):
                    if int_value != 80:
                        if axis_command:
                            return fail(24, k)
                        axis_command = "motion"
                    group = "G1"
                    k_cmd = k
                    motion = int_value
                    if int_value == 38:
                        if mantissa not in (20, 30, 40, 50):
                            return fail(20, k)
                        motion = 100 + int_value + mantissa // 10
                        mantissa = 0
                elif int_value in (17, 18, 19):
                    group, plane = "G2", int_value - 17
                elif int_value in (90, 91):
                    if mantissa == 0:
                        group, incremental = "G3", int_value == 91
                    else:
                        group = "G4"
                        if mantissa != 10 or int_value == 90:
                            return fail(20, k)  # G90.1 not supported
                        mantissa = 0
                elif int_value in (93, 94):
                    group, inverse_time = "G5", int_value == 93
                elif int_value in (20, 21):
                    group, inches = "G6", int_value == 20
                elif int_value == 40:
                    group = "G7"
                elif int_value in (43, 49):
                    group = "G8"
                    if axis_command:
                        return fail(24, k)
                    axis_command = "tlo"
                    if int_value == 49:
                        tool_length = "cancel"
                    elif mantissa == 10:
                        tool_length = "dynamic"
                    else:
                        return fail(20, k)  # G43 without .1
                    mantissa = 0
                elif 54 <= int_value <= 59:
                    group, coord_select = "G12", int_value - 54
                elif int_value == 61:
                    group = "G13"
                    if mantissa != 0:
                        return fail(20, k)
                else:
                    return fail(20, k)
                if mantissa > 0:
                    return fail(23, k)
                if group in groups:
                    return fail(21, k)
                groups.add(group)
            elif letter == "M":
                if mantissa > 0:
                    return fail(23, k)
                if int_value in (0, 1, 2, 30):
                    group = "M4"
                    if int_value == 0:
                        program_flow = "pause"
                    elif int_value in (2, 30):
                        program_flow = "end"
                elif int_value in (3, 4, 5):
                    group = "M7"
                    spindle = {3: 1, 4: -1, 5: 0}[int_value]
                elif int_value in (8, 9):  # M7 only with ENABLE_M7 (off by default)
                    group = "M8"
                    coolant = 2 if int_value == 8 else 0
                else:
                    return fail(20, k)  # M6 and the rest
                if group in groups:
                    return fail(21, k)
                groups.add(group)
            else:
                if letter not in "FIJKLNPRSTXYZ":
                    return fail(20, k)  # A B C D E H O Q U V W ...
                if letter in values:
                    return fail(25, k)
                if letter in "FNPTS" and value < 0:
                    return fail(4, k)
                if letter == "T" and value > GRBL_MAX_TOOL_NUMBER:
                    return fail(38, k)
                values[letter] = value
                widx[letter] = k
        used = dict(values)  # value words still unused (gcode.c value_words)

        def fail_word(code: int, letter: str) -> GrblResult:
            return fail(code, widx.get(letter, k_cmd))

        # ---- STEP 3: error checks, in gcode.c's order
        axis_words = [a for a in _AXES if a in values]
        if axis_words and not axis_command:
            axis_command = "motion"
        if "N" in values and values["N"] > GRBL_MAX_LINE_NUMBER:
            return fail_word(27, "N")
        f = values.get("F", 0.0)
        if inverse_time:
            if axis_command == "motion" and motion not in (_NONE, _SEEK) and "F" not in values:
                return fail(22, k_cmd)
        elif not gc.inverse_time:
            if "F" in values:
                f = f * MM_PER_INCH if inches else f
            else:
                f = gc.feed
        s = values.get("S", gc.spindle_speed)
        if non_modal == 4:
            if "P" not in values:
                return fail(28, k_cmd)
            used.pop("P", None)
        a0, a1, alin = {0: (0, 1, 2), 1: (2, 0, 1), 2: (1, 2, 0)}[plane]
        xyz = [values.get(a, 0.0) * (MM_PER_INCH if inches else 1.0) for a in _AXES]
        tlo_z = xyz[2]
        if axis_command == "tlo" and tool_length == "dynamic" and axis_words != ["Z"]:
            return fail(37, k_cmd)
        block_coord = list(gc.coord_systems[coord_select])
        ijk = [0.0, 0.0, 0.0]
        new_g92 = None
        if non_modal == 10:
            if not axis_words:
                return fail(26, k_cmd)
            if "P" not in values and "L" not in values:
                return fail(28, k_cmd)
            p = math.trunc(values.get("P", 0.0))
            if p > GRBL_N_COORDINATE_SYSTEM:
                return fail_word(29, "P")
            L = math.trunc(values.get("L", 0.0)) & 0xFF
            if L != 20:
                if L == 2:
                    if "R" in values:
                        return fail_word(20, "R")
                else:
                    return fail_word(20, "L")
            used.pop("L", None)
            used.pop("P", None)
            sel = p - 1 if p > 0 else coord_select
            data = list(gc.coord_systems[sel])
            for ax in range(3):
                if _AXES[ax] in values:
                    if L == 20:
                        data[ax] = gc.position[ax] - gc.coord_offset[ax] - xyz[ax]
                        if ax == 2:
                            data[ax] -= gc.tool_length_offset
                    else:
                        data[ax] = xyz[ax]
            g10 = (sel, data)
        elif non_modal == 92:
            if not axis_words:
                return fail(26, k_cmd)
            new_g92 = [
                (gc.position[ax] - block_coord[ax] - xyz[ax]
                 - (gc.tool_length_offset if ax == 2 else 0.0))
                if _AXES[ax] in values else gc.coord_offset[ax]
                for ax in range(3)
            ]  # fmt: skip
        else:
            if axis_command != "tlo" and axis_words:
                for ax in range(3):
                    if _AXES[ax] not in values:
                        xyz[ax] = gc.position[ax]
                    elif non_modal != 53:
                        if not incremental:
                            xyz[ax] += block_coord[ax] + gc.coord_offset[ax]
                            if ax == 2:
                                xyz[ax] += gc.tool_length_offset
                        else:
                            xyz[ax] += gc.position[ax]
            if non_modal in (28, 30):
                home = list(gc.home[0 if non_modal == 28 else 1])
                if axis_words:
                    for ax in range(3):
                        if _AXES[ax] not in values:
                            home[ax] = gc.position[ax]
                else:
                    axis_command = ""
                ijk = home
            elif non_modal == 53 and motion not in (_SEEK, _LINEAR):
                return fail(30, k_cmd)
        arc_travel = arc_radius = 0.0
        if motion == _NONE:
            if axis_words:
                return fail_word(31, axis_words[0])
        elif axis_command == "motion":
            if motion == _SEEK:
                if not axis_words:
                    axis_command = ""
            else:
                if f == 0.0:
                    return fail(22, k_cmd)
                if motion == _LINEAR:
                    if not axis_words:
                        axis_command = ""
                elif motion in (_CW, _CCW):
                    if not axis_words:
                        return fail(26, k_cmd)
                    if _AXES[a0] not in values and _AXES[a1] not in values:
                        return fail_word(32, axis_words[0])
                    x = xyz[a0] - gc.position[a0]
                    y = xyz[a1] - gc.position[a1]
                    if "R" in values:
                        used.pop("R")
                        if xyz == gc.position:
                            return fail_word(33, "R")
                        r = values["R"] * (MM_PER_INCH if inches else 1.0)
                        h = 4.0 * r * r - x * x - y * y
                        if h < 0:
                            return fail_word(34, "R")
                        h = -math.sqrt(h) / math.hypot(x, y)
                        if motion == _CCW:
                            h = -h
                        if r < 0:
                            h, r = -h, -r
                        ijk[a0] = 0.5 * (x - y * h)
                        ijk[a1] = 0.5 * (y + x * h)
                        arc_radius = r
                    else:
                        ia, ib = _AXES[a0], _AXES[a1]
                        off = {"X": "I", "Y": "J", "Z": "K"}
                        if off[ia] not in values and off[ib] not in values:
                            return fail(35, k_cmd)
                        for w in "IJK":
                            used.pop(w, None)
                        for ax, w in enumerate("IJK"):
                            ijk[ax] = values.get(w, 0.0) * (MM_PER_INCH if inches else 1.0)
                        x -= ijk[a0]
                        y -= ijk[a1]
                        target_r = math.hypot(x, y)
                        arc_radius = math.hypot(ijk[a0], ijk[a1])
                        delta_r = abs(target_r - arc_radius)
                        if delta_r > 0.005 and (delta_r > 0.5 or delta_r > 0.001 * arc_radius):
                            return fail(33, k_cmd)
                    # mc_arc's angular travel
                    ra0, ra1 = -ijk[a0], -ijk[a1]
                    rt0 = xyz[a0] - (gc.position[a0] + ijk[a0])
                    rt1 = xyz[a1] - (gc.position[a1] + ijk[a1])
                    t = math.atan2(ra0 * rt1 - ra1 * rt0, ra0 * rt0 + ra1 * rt1)
                    eps = 5e-7  # ARC_ANGULAR_TRAVEL_EPSILON
                    if motion == _CW:
                        t = t - 2 * math.pi if t >= -eps else t
                    else:
                        t = t + 2 * math.pi if t <= eps else t
                    arc_travel = t
                elif motion >= 100:  # G38.x probing
                    if not axis_words:
                        return fail(26, k_cmd)
                    if xyz == gc.position:
                        return fail(33, k_cmd)
        for w in "NFST":
            used.pop(w, None)
        if axis_command:
            for w in _AXES:
                used.pop(w, None)
        if used:
            first = min(used, key=lambda w: widx[w])
            return fail_word(36, first)

        # ---- STEP 4: execute (the parser state; motion is counted, not run)
        sync = False
        if s != gc.spindle_speed and gc.spindle != 0:
            sync = True
        if spindle != gc.spindle or coolant != gc.coolant:
            sync = True
        gc.inverse_time = inverse_time
        gc.feed = f
        gc.spindle_speed = s
        if "T" in values:
            gc.tool = math.trunc(values["T"])
        gc.spindle, gc.coolant = spindle, coolant
        dwell = values.get("P", 0.0) if non_modal == 4 else 0.0
        gc.plane, gc.inches = plane, inches
        if axis_command == "tlo":
            gc.tool_length_offset = tlo_z if tool_length == "dynamic" else 0.0
        if coord_select != gc.coord_select:
            gc.coord_select = coord_select
        gc.incremental = incremental
        blocks = 0
        if non_modal == 10:
            sel, data = g10
            gc.coord_systems[sel] = data
        elif non_modal in (28, 30):
            if axis_command:
                blocks += xyz != gc.position
            blocks += ijk != (xyz if axis_command else gc.position)
            gc.position = list(ijk)
        elif non_modal == 281:
            gc.home[0] = list(gc.position)
        elif non_modal == 301:
            gc.home[1] = list(gc.position)
        elif non_modal == 92:
            gc.coord_offset = new_g92
        elif non_modal == 921:
            gc.coord_offset = [0.0, 0.0, 0.0]
        gc.motion = motion
        if motion != _NONE and axis_command == "motion":
            if motion in (_CW, _CCW):
                blocks += _arc_segments(arc_travel, arc_radius, self.arc_tolerance_mm)
            else:
                blocks += xyz != gc.position
            gc.position = list(xyz)
        if program_flow == "end":
            gc.motion, gc.plane, gc.incremental, gc.inverse_time = _LINEAR, 0, False, False
            gc.coord_select, gc.spindle, gc.coolant = 0, 0, 0
        sync = sync or non_modal == 4 or bool(program_flow)
        return GrblResult(
            0,
            sync=sync,
            dwell_s=dwell,
            planner_blocks=int(blocks),
            program_flow=program_flow,
            line_number=int(values.get("N", 0)),
        )

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
