"""GRBL 1.1h's gcode.c ``gc_execute_line``, steps 2 and 3 (private to :mod:`planning.nc.grbl`):
the words of a line imported and checked, then the block checked in gcode.c's order, over one
:class:`_Block`; :class:`GrblState` is what a line inherits, :class:`GrblResult` GRBL's answer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

GRBL_MAX_LINE_NUMBER = 10_000_000  # gcode.c MAX_LINE_NUMBER
GRBL_MAX_TOOL_NUMBER = 255  # gcode.c MAX_TOOL_NUMBER
GRBL_N_COORDINATE_SYSTEM = 6  # G54..G59
MM_PER_INCH = 25.4


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
