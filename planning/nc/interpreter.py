"""The NC interpreter: blocks of text in, canonical :class:`~planning.nc.Motion` segments out.

Two ways in:

* whole programs — :func:`interpret` (text, :class:`~planning.nc.Program` or lines) and
  :func:`interpret_file` (streams the file line by line; memory grows only with the segment
  arrays, so million-block programs are fine);
* one block at a time — :class:`Interpreter`: ``it.execute("G1 X10 F300")`` returns that block's
  segments as a (small) Motion and updates ``it.state`` (a :class:`~planning.nc.ModalState`, copy
  it with ``it.state.copy()``). The simulated controllers use this as blocks arrive over serial.

Semantics (RS-274 / Fanuc flavour; ``dialect`` only changes G4/G82 ``P``: milliseconds on Fanuc,
seconds on GRBL):

* Within a block: G-codes first (plane, units, distance modes, ...), then F S T, M6, M3/M4/M5,
  M7/M8/M9, dwell, motion, then M0/M1/M2/M30. Units switched in a block apply to that block's words.
* Positions and feeds are converted to mm and mm/min; positions are in the machine frame, i.e.
  program coordinates plus the active work offset G54..G59 (zero unless ``work_offsets_mm`` is
  given). G53 moves to machine coordinates for one block.
* G40/G41/G42 (with D) and G43/G49 (with H) are recorded in the state; the motion is the
  programmed tool-tip path (no cutter or length compensation applied).
* A/B/C words are recorded in ``state.rotary_deg`` only.
* G80..G83 with G98/G99 expand to rapid/feed/dwell moves (:mod:`planning.nc.canned`).
* G28 / G30 (return to the reference / second reference point, P2 only), as on Fanuc: the axes
  named rapid to the intermediate point their words give (program coordinates, G90 or G91; ``G91
  G28 Z0`` goes straight up), then to the reference point, which is in machine coordinates (the
  work offset does not apply, as with G53). Axes not named do not move. The points come from the
  machine config (``reference_point_mm`` / ``second_reference_point_mm``) or the
  ``reference_mm`` / ``second_reference_mm`` options; with neither, machine zero = work zero
  (0, 0, 0) is used and a warning says so. GRBL dialect: a G28/G30 with no axis word moves all
  axes straight to the point (Fanuc: an error). Tool length compensation is not applied, so the
  point is where the programmed tool tip goes.
* G93 inverse-time feed: every feed move (G1/G2/G3) needs its own F, and takes 1/F minutes; the
  Motion gets ``feed_mm_min = path length * F``. F is not modal under G93, and switching between
  G93 and G94 leaves no feed set (program F again), as in RS-274/NGC. Canned cycles and feed moves
  with no X/Y/Z travel (rotary only) under G93 are errors.
* After M2/M30 or the closing ``%`` nothing more is executed; blocks with words there give a
  warning.
* Strict mode (default) raises :class:`~planning.nc.NCError` for unknown G/M codes, unknown
  letters and words no code uses; lenient mode records them as
  :class:`~planning.nc.NCWarning` in ``warnings`` and goes on. Errors that leave the motion
  unknown (bad arcs, feed move with no F, ...) raise in both modes.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING

from planning.nc import _lexer
from planning.nc._codes import (
    FAST_LETTERS,
    G_GROUP,
    KNOWN_M,
    LETTERS,
    LETTERS_GM,
    M_GROUP,
    MOTION_MODE,
    gkey,
    gname,
)
from planning.nc.arcs import PLANE_AXES, arc_length_mm, center_from_r, check_radius
from planning.nc.canned import execute_canned
from planning.nc.errors import NCError, NCWarning
from planning.nc.motion import ARC_CCW, ARC_CW, DWELL, LINE, RAPID, Motion, MotionBuilder
from planning.nc.state import CannedCycle, ModalState

if TYPE_CHECKING:
    from analysis.config import MachineConfig

INCH_MM = 25.4
DEFAULT_ARC_TOLERANCE_MM = 0.002  # MachineConfig's default
NAN = math.nan


class _NullSink:
    """Builder stand-in that drops segments (modal state only)."""

    class _Drop:
        def extend(self, _: object) -> None:
            pass

    fbuf = ibuf = _Drop()


class Interpreter:
    """Executes NC blocks one at a time, tracking all modal state.

    Parameters
    ----------
    machine : MachineConfig, optional
        Gives the arc radius tolerance and the dialect (else 0.002 mm and ``"fanuc"``).
    strict : bool
        Unknown codes/letters and unused words raise (True) or become warnings (False).
    file : str
        Name used in error messages.
    dialect : {"fanuc", "grbl"}, optional
        Overrides the machine's; only the unit of G4/G82 ``P`` depends on it.
    block_delete : bool
        The block-delete switch: True skips blocks starting with ``/``.
    arc_tolerance_mm : float, optional
        Overrides the machine's arc radius tolerance, mm.
    work_offsets_mm : mapping {54..59: (x, y, z)}, optional
        Work offsets added to program coordinates; default all zero.
    peck_clearance_mm : float
        G83 re-entry clearance above the previous peck, mm.
    reference_mm, second_reference_mm : (x, y, z), optional
        Machine coordinates of the G28 / G30 points, mm; override the machine's.
    state : ModalState, optional
        Start from this state (copied), e.g. to resume a program at a block.

    Attributes
    ----------
    state : ModalState
        The modal state after the blocks executed so far.
    warnings : list of NCWarning
        What lenient mode skipped, and blocks ignored after the program end.
    blocks_seen : int
        Number of blocks executed so far (the default block index of the next one).
    """

    def __init__(
        self,
        machine: MachineConfig | None = None,
        *,
        strict: bool = True,
        file: str = "<program>",
        dialect: str | None = None,
        block_delete: bool = True,
        arc_tolerance_mm: float | None = None,
        work_offsets_mm: dict[int, Sequence[float]] | None = None,
        peck_clearance_mm: float = 0.1,
        reference_mm: Sequence[float] | None = None,
        second_reference_mm: Sequence[float] | None = None,
        state: ModalState | None = None,
    ) -> None:
        self.strict = strict
        self.file = str(file)
        self.dialect = dialect or (machine.dialect if machine is not None else "fanuc")
        if self.dialect not in ("fanuc", "grbl"):
            raise NCError(f"dialect must be 'fanuc' or 'grbl', got {self.dialect!r}", file=file)
        self.block_delete = block_delete
        tol = arc_tolerance_mm
        if tol is None:
            tol = machine.arc_radius_tolerance_mm if machine is not None else None
        self.arc_tolerance_mm = DEFAULT_ARC_TOLERANCE_MM if tol is None else float(tol)
        self.work_offsets_mm = {
            k: tuple(float(c) for c in v) for k, v in (work_offsets_mm or {}).items()
        }
        self.peck_clearance_mm = float(peck_clearance_mm)
        if reference_mm is None and machine is not None:
            reference_mm = machine.reference_point_mm
        if second_reference_mm is None and machine is not None:
            second_reference_mm = machine.second_reference_point_mm
        # None: machine zero = work zero, said once in a warning when a G28/G30 needs it
        self._reference_mm = {280: reference_mm, 300: second_reference_mm or reference_mm}
        self._reference_warned = False
        self._inverse_f = NAN  # this block's F under G93 (1/min)
        inf = math.inf
        self._feed_max_mm_min = machine.feed_max_mm_min if machine is not None else inf
        self._spindle_max_rpm = machine.spindle_max_rpm if machine is not None else inf
        self.state = state.copy() if state is not None else ModalState()
        self.warnings: list[NCWarning] = []
        self.blocks_seen = 0

    # ------------------------------------------------------------------ public API
    def execute(self, text: str, *, line: int | None = None, block: int | None = None) -> Motion:
        """Execute one block's text; return its segments (often 0 or 1, more for canned cycles).

        ``line`` (1-based) and ``block`` (0-based) label the segments and errors; by default the
        block count so far is used. On NCError the state is left as it was before the block.
        """
        out = MotionBuilder()
        b = self.blocks_seen if block is None else block
        self._execute_safe(text, b + 1 if line is None else line, b, out)
        return out.build()

    def run(self, lines: Iterable[str], *, first_line: int = 1) -> Motion:
        """Execute many blocks (one per line, block i = line i + 1); return all their segments."""
        out = MotionBuilder()
        self._run(lines, first_line, out)
        return out.build()

    def skip(self, lines: Iterable[str], *, first_line: int = 1) -> None:
        """Execute blocks for their modal effect only (no segments are kept)."""
        self._run(lines, first_line, _NullSink())

    # ------------------------------------------------------------------ internals
    def _run(self, lines: Iterable[str], first_line: int, out: MotionBuilder | _NullSink) -> None:
        block = first_line - 1
        execute = self._execute
        for raw in lines:
            execute(raw, block + 1, block, out)
            block += 1
        self.blocks_seen = block

    def _execute_safe(self, raw: str, line: int, block: int, out: MotionBuilder) -> None:
        saved = self.state.copy()
        try:
            self._execute(raw, line, block, out)
        except NCError:
            self.state = saved
            raise
        self.blocks_seen = block + 1

    def _problem(self, raw: str, index: int, reason: str, line: int) -> None:
        """Strict: raise; lenient: record a warning about word ``index`` of the block."""
        err = _lexer.word_error(raw, index, reason, self.file, line)
        if self.strict:
            raise err
        self.warnings.append(NCWarning(err.reason, err.file, err.line, err.column, err.word))

    def _fail(self, raw: str, letter_or_index: str | int, reason: str, line: int) -> NCError:
        idx = letter_or_index
        if isinstance(idx, str):
            idx = _lexer.find_word(raw, idx)
        return _lexer.word_error(raw, idx, reason, self.file, line)

    def _execute(self, raw: str, line: int, block: int, out: MotionBuilder | _NullSink) -> None:
        words, flag = _lexer.block_words(raw, self.file, line)
        st = self.state
        if flag:
            if flag == 2:
                st.tape_marks += 1
                return
            if self.block_delete:
                return
        if not words:
            return
        if st.ended or st.tape_marks >= 2:
            self.warnings.append(
                NCWarning(
                    "block after the program end (M2/M30 or closing %) is ignored",
                    self.file,
                    line,
                    1,
                    raw.strip()[:40],
                )
            )
            return
        st.stopped = False
        gcodes: list[tuple[int, int]] | None = None
        mcodes: list[tuple[int, int]] | None = None
        v = dict(words)
        if len(v) == len(words) and v.keys() <= LETTERS_GM:
            # fast path (most blocks): no letter twice, at most one G and one M, all known
            g = v.pop("G", None)
            if g is not None:
                key = gkey(g)
                if key not in G_GROUP:
                    v = None  # let the slow path report it
                else:
                    gcodes = [(key, words.index(("G", g)))]
            m = v.pop("M", None) if v is not None else None
            if m is not None:
                key = round(float(m) * 10.0)
                if key % 10 or key // 10 not in KNOWN_M:
                    v = None
                else:
                    mcodes = [(key, words.index(("M", m)))]
        else:
            v = None
        if v is None:
            gcodes, mcodes, v = self._sort_words(raw, words, line)

        # ---- G codes: modes first so this block's words use them
        explicit_motion = False
        dwell = g53 = False
        home: tuple[int, int] | None = None  # (G28 or G30 key, word index)
        self._inverse_f = NAN
        if gcodes is not None:
            prev_motion = st.motion
            groups: dict[int, int] = {}
            for key, k in gcodes:
                grp = G_GROUP[key]
                if grp in groups:
                    other = groups[grp]
                    raise _lexer.word_error(
                        raw,
                        k,
                        f"{gname(key)} and {gname(other)} are in the same modal group "
                        f"(group {grp}) and cannot share a block",
                        self.file,
                        line,
                    )
                groups[grp] = key
                if grp == 9:  # G80; a G0..G3 in the same block then sets the motion mode
                    g1 = groups.get(1)
                    if g1 is not None and g1 >= 810:
                        raise _lexer.word_error(
                            raw, k, f"G80 and {gname(g1)} cannot share a block", self.file, line
                        )
                    if g1 is None:
                        st.motion = 80
                        explicit_motion = True
                elif grp == 1:
                    if 9 in groups and key >= 810:
                        raise _lexer.word_error(
                            raw, k, f"{gname(key)} and G80 cannot share a block", self.file, line
                        )
                    st.motion = MOTION_MODE[key]
                    explicit_motion = True
                elif grp == 0:
                    if key == 40:
                        dwell = True
                    elif key == 530:
                        g53 = True
                    else:
                        home = (key, k)
                elif grp == 2:
                    st.plane = key // 10
                elif grp == 6:
                    st.inch = key == 200
                elif grp == 3:
                    st.absolute = key == 900
                elif grp == 4:
                    st.arc_absolute = key == 901
                elif grp == 5:
                    if key // 10 != st.feed_mode:  # F means something else now: set it again
                        st.feed_mode = key // 10
                        st.feed_mm_min = NAN
                elif grp == 7:
                    st.cutter_comp = key // 10
                elif grp == 8:
                    st.tool_length = key // 10
                elif grp == 10:
                    st.retract_initial = key == 980
                else:  # 12, work offsets
                    st.work_offset = key // 10
            if explicit_motion and (st.motion >= 81) != (prev_motion >= 81):
                # leaving a cycle, or starting one: its initial level is the Z here
                st.canned = CannedCycle(initial_z_mm=st.position_mm[2])

        scale = INCH_MM if st.inch else 1.0
        # ---- other words
        if not v.keys() <= FAST_LETTERS:
            self._words(raw, v, scale, line, dwell or (home is not None and home[0] == 300))
        else:  # only X Y Z F N: the common block
            if "F" in v:
                self._feed(raw, v, scale, line)
            if "N" in v:
                st.sequence_number = self._whole(raw, v, "N", line)

        # ---- M codes before motion (tool change, spindle, coolant)
        end = False
        if mcodes is not None:
            if len(mcodes) > 1:
                self._check_m_groups(raw, mcodes, line)
            for key, _k in mcodes:
                m = key // 10
                if m == 6:
                    st.tool = st.tool_selected
                elif m == 3:
                    st.spindle_dir = 1
                elif m == 4:
                    st.spindle_dir = -1
                elif m == 5:
                    st.spindle_dir = 0
                elif m == 7 or m == 8:
                    st.coolant = True
                elif m == 9:
                    st.coolant = False
                elif m == 0 or m == 1:
                    st.stopped = True
                else:
                    end = True

        # ---- dwell
        if dwell:
            if "Y" in v or "Z" in v or ("X" in v and "P" in v):
                raise self._fail(
                    raw,
                    next(L for L in "YZX" if L in v),
                    "G4 dwell cannot share its block with a move",
                    line,
                )
            self._dwell(raw, v, line, block, out)

        # ---- motion
        has_axes = ("X" in v or "Y" in v or "Z" in v) and not dwell
        mode = st.motion
        if home is not None:
            if explicit_motion and mode >= 81:
                raise _lexer.word_error(
                    raw,
                    home[1],
                    f"{gname(home[0])} and G{mode} cannot share a block",
                    self.file,
                    line,
                )
            self._home(raw, v, scale, line, block, out, *home)
        elif has_axes or (
            explicit_motion and mode >= 2 and mode <= 3 and ("I" in v or "J" in v or "K" in v)
        ):
            if mode == 80:
                raise self._fail(
                    raw,
                    next(L for L in "XYZ" if L in v),
                    "axis word with no motion mode in force (G80 cancelled it; program G0/G1)",
                    line,
                )
            if mode >= 81:
                execute_canned(self, raw, v, scale, line, block, out)
            else:
                self._move(raw, v, scale, line, block, out, mode, g53)
        elif g53:
            raise self._fail(raw, 0, "G53 needs an axis word (X, Y or Z)", line)
        if end:
            st.ended = True

    def _sort_words(self, raw: str, words, line: int):
        """G codes, M codes (with their word index) and the other words; reports unknown codes,
        unknown letters and repeated addresses."""
        gcodes: list[tuple[int, int]] | None = None
        mcodes: list[tuple[int, int]] | None = None
        v: dict[str, str] = {}
        for k, (letter, num) in enumerate(words):
            if letter == "G":
                key = gkey(num)
                if key not in G_GROUP:
                    self._problem(raw, k, f"unknown G-code {gname(key)}", line)
                elif gcodes is None:
                    gcodes = [(key, k)]
                else:
                    gcodes.append((key, k))
            elif letter == "M":
                key = round(float(num) * 10.0)
                if key % 10 or key // 10 not in KNOWN_M:
                    self._problem(raw, k, f"unknown M-code M{key / 10:g}", line)
                elif mcodes is None:
                    mcodes = [(key, k)]
                else:
                    mcodes.append((key, k))
            elif letter not in LETTERS:
                self._problem(raw, k, f"unknown address letter {letter}", line)
            elif letter in v:
                raise _lexer.word_error(
                    raw, k, f"address {letter} appears twice in the block", self.file, line
                )
            else:
                v[letter] = num
        return gcodes, mcodes, v

    def _words(self, raw: str, v: dict[str, str], scale: float, line: int, p_used: bool) -> None:
        """F S T D H O N P Q L R I J K and A B C: checks and recording (``p_used``: G4 or G30 in
        the block takes the P word)."""
        st = self.state
        if "F" in v:
            self._feed(raw, v, scale, line)
        if "S" in v:
            s = float(v["S"])
            if s < 0.0:
                raise self._fail(raw, "S", "spindle speed S must be >= 0 rpm", line)
            if s > self._spindle_max_rpm:
                self._note(
                    raw,
                    "S",
                    f"S {s:g} rpm exceeds the machine's spindle_max_rpm {self._spindle_max_rpm:g}",
                    line,
                )
            st.spindle_speed_rpm = s
        for letter in ("T", "D", "H", "O", "N"):
            if letter in v:
                n = self._whole(raw, v, letter, line)
                if letter == "T":
                    st.tool_selected = n
                elif letter == "D":
                    st.cutter_comp_d = n
                elif letter == "H":
                    st.tool_length_h = n
                elif letter == "O":
                    st.program_number = n
                else:
                    st.sequence_number = n
        for letter in ("A", "B", "C"):
            if letter in v:
                st.rotary_deg[letter] = float(v[letter])
        mode = st.motion
        used = set()
        if mode in (2, 3):
            used.update("IJKR")
        if mode >= 81:
            used.update("RLPQ")
        if p_used:
            used.add("P")
        for letter in "IJKRPQL":
            if letter in v and letter not in used:
                self._problem(
                    raw,
                    _lexer.find_word(raw, letter),
                    f"word {letter} is not used by any code in force (motion G{mode})",
                    line,
                )

    def _whole(self, raw: str, v: dict[str, str], letter: str, line: int) -> int:
        """The value of a T D H O N word: a whole number 0..999999999."""
        n = float(v[letter])
        if n < 0 or n != int(n) or n > 999_999_999:
            raise self._fail(
                raw,
                letter,
                f"{letter} must be a whole number in 0..999999999, got {v[letter]}",
                line,
            )
        return int(n)

    def _feed(self, raw: str, v: dict[str, str], scale: float, line: int) -> None:
        if self.state.feed_mode == 93:
            f = float(v["F"])
            if not f > 0.0:
                raise self._fail(
                    raw,
                    "F",
                    "inverse-time feed F must be > 0 (1/min: the move takes 1/F min)",
                    line,
                )
            self._inverse_f = f
            return
        f = float(v["F"]) * scale
        if not f > 0.0:
            raise self._fail(raw, "F", "feed F must be > 0 (mm/min, or in/min under G20)", line)
        if f > self._feed_max_mm_min:
            self._note(
                raw,
                "F",
                f"feed {f:g} mm/min exceeds the machine's feed_max_mm_min "
                f"{self._feed_max_mm_min:g}",
                line,
            )
        self.state.feed_mm_min = f

    def _note(self, raw: str, letter_or_index: str | int, reason: str, line: int) -> None:
        """A warning in both modes (the block is still executed as written)."""
        err = self._fail(raw, letter_or_index, reason, line)
        self.warnings.append(NCWarning(err.reason, err.file, err.line, err.column, err.word))

    def _check_m_groups(self, raw: str, mcodes: list[tuple[int, int]], line: int) -> None:
        seen: dict[str, int] = {}
        for key, k in mcodes:
            grp = M_GROUP[key // 10]
            if grp in seen:
                raise _lexer.word_error(
                    raw,
                    k,
                    f"M{key // 10} and M{seen[grp]} are both {grp} codes and cannot share a block",
                    self.file,
                    line,
                )
            seen[grp] = key // 10

    def _seg(
        self, out, kind: int, p0, p1, c, feed: float, dwell_s: float, line: int, block: int
    ) -> None:
        st = self.state
        out.fbuf.extend(
            (
                p0[0],
                p0[1],
                p0[2],
                p1[0],
                p1[1],
                p1[2],
                c[0],
                c[1],
                c[2],
                feed,
                st.spindle_dir * st.spindle_speed_rpm,
                dwell_s,
            )
        )
        out.ibuf.extend((kind, st.plane, st.tool, st.coolant, line, block))

    def _dwell(self, raw: str, v: dict[str, str], line: int, block: int, out) -> None:
        if "P" in v:
            t = float(v["P"])
            t = t / 1000.0 if self.dialect == "fanuc" else t
            letter = "P"
        elif "X" in v:
            t, letter = float(v["X"]), "X"
        else:
            raise self._fail(raw, 0, "G4 dwell needs P (ms on Fanuc, s on GRBL) or X (s)", line)
        if t < 0:
            raise self._fail(raw, letter, "dwell time must be >= 0 s", line)
        p = self.state.position_mm
        self._seg(out, DWELL, p, p, (NAN, NAN, NAN), NAN, t, line, block)

    def _target(self, v: dict[str, str], scale: float, g53: bool) -> tuple[float, float, float]:
        st = self.state
        x, y, z = st.position_mm
        if g53:
            ox = oy = oz = 0.0
        else:
            ox, oy, oz = self.work_offsets_mm.get(st.work_offset, (0.0, 0.0, 0.0))
        if st.absolute or g53:
            if "X" in v:
                x = float(v["X"]) * scale + ox
            if "Y" in v:
                y = float(v["Y"]) * scale + oy
            if "Z" in v:
                z = float(v["Z"]) * scale + oz
        else:
            if "X" in v:
                x += float(v["X"]) * scale
            if "Y" in v:
                y += float(v["Y"]) * scale
            if "Z" in v:
                z += float(v["Z"]) * scale
        return x, y, z

    def _need_feed(self, raw: str, line: int, length_mm: float | None = None) -> float:
        """The feed of a feed move, mm/min; under G93 from the move's ``length_mm`` (None: a
        canned cycle, which G93 does not allow)."""
        if self.state.feed_mode != 93:
            f = self.state.feed_mm_min
            if f != f:
                raise self._fail(raw, 0, "feed move with no feed rate set (program F first)", line)
            return f
        if length_mm is None:
            raise self._fail(raw, 0, "canned cycles cannot run under inverse-time feed G93", line)
        if self._inverse_f != self._inverse_f:
            raise self._fail(
                raw, 0, "under inverse-time feed G93 every feed move needs its own F (1/min)", line
            )
        if not length_mm > 0.0:
            raise self._fail(
                raw,
                0,
                "inverse-time (G93) feed move with no X/Y/Z travel: its time 1/F cannot be "
                "represented (rotary-only moves are not modelled)",
                line,
            )
        f = length_mm * self._inverse_f
        if f > self._feed_max_mm_min:
            self._note(
                raw,
                "F",
                f"inverse-time feed gives {f:g} mm/min, above the machine's feed_max_mm_min "
                f"{self._feed_max_mm_min:g}",
                line,
            )
        return f

    def _move(self, raw, v, scale, line, block, out, mode: int, g53: bool) -> None:
        st = self.state
        p0 = st.position_mm
        p1 = self._target(v, scale, g53)
        if g53 and mode not in (0, 1):
            raise self._fail(raw, 0, "G53 needs G0 or G1 in force", line)
        if mode <= 1:  # inlined _seg: this is the hot path of big programs
            if mode == 0:
                kind, feed = RAPID, NAN
            else:
                kind, feed = LINE, st.feed_mm_min
                if feed != feed:
                    feed = self._need_feed(raw, line, math.dist(p0, p1))
            out.fbuf.extend(
                (
                    p0[0],
                    p0[1],
                    p0[2],
                    p1[0],
                    p1[1],
                    p1[2],
                    NAN,
                    NAN,
                    NAN,
                    feed,
                    st.spindle_dir * st.spindle_speed_rpm,
                    0.0,
                )
            )
            out.ibuf.extend((kind, st.plane, st.tool, st.coolant, line, block))
        else:
            c = self._arc_center(raw, v, scale, line, p0, p1, mode == 2)
            length = arc_length_mm(p0, p1, c, st.plane, mode == 2) if st.feed_mode == 93 else None
            feed = self._need_feed(raw, line, length)
            self._seg(out, ARC_CW if mode == 2 else ARC_CCW, p0, p1, c, feed, 0.0, line, block)
        st.position_mm = p1

    def _home(self, raw, v, scale, line, block, out, key: int, k: int) -> None:
        """G28 / G30 (word ``k`` of the block): the named axes rapid to the intermediate point,
        then to the reference point (machine coordinates); the others stay."""
        st = self.state
        code = gname(key)
        if key == 300 and "P" in v and float(v["P"]) != 2.0:
            raise self._fail(
                raw, "P", "only the second reference point (G30 P2) is configured", line
            )
        named = [a for a in range(3) if "XYZ"[a] in v]
        if named:
            mid = self._target(v, scale, False)
        elif self.dialect == "grbl":  # GRBL: no axis word = all axes straight to the point
            named, mid = [0, 1, 2], st.position_mm
        else:
            raise self._fail(
                raw, k, f"{code} needs the axes to return (X, Y, Z), e.g. G91 {code} Z0", line
            )
        ref = self._reference_mm[key]
        if ref is None:
            ref = (0.0, 0.0, 0.0)
            if not self._reference_warned:
                self._reference_warned = True
                self._note(
                    raw,
                    k,
                    f"no machine given: the {code} point is taken as machine zero = work zero "
                    "(0, 0, 0) mm (give a machine config with reference_mm)",
                    line,
                )
        end = list(mid)
        for a in named:
            end[a] = float(ref[a])
        p0, p1 = st.position_mm, tuple(end)
        nowhere = (NAN, NAN, NAN)
        for a, b in ((p0, mid), (mid, p1)):
            if a != b:
                self._seg(out, RAPID, a, b, nowhere, NAN, 0.0, line, block)
        st.position_mm = p1

    def _arc_center(self, raw, v, scale, line, p0, p1, cw: bool) -> tuple[float, float, float]:
        st = self.state
        ia, ib, ic = PLANE_AXES[st.plane]
        tol = self.arc_tolerance_mm
        ijk = "IJK"
        la, lb, ln = ijk[ia], ijk[ib], ijk[ic]
        has_r = "R" in v
        has_ijk = la in v or lb in v
        if ln in v:
            self._problem(
                raw,
                _lexer.find_word(raw, ln),
                f"{ln} is not an in-plane centre word for G{st.plane} arcs",
                line,
            )
        a0, b0, a1, b1 = p0[ia], p0[ib], p1[ia], p1[ib]
        try:
            if has_r and has_ijk:
                raise ValueError("give the arc by R or by I/J/K, not both")
            if has_r:
                r = float(v["R"]) * scale
                ca, cb = center_from_r(a0, b0, a1, b1, r, cw, tol)
            elif has_ijk:
                if st.arc_absolute:
                    if not (la in v and lb in v):
                        raise ValueError(f"G90.1 (absolute centre) needs both {la} and {lb}")
                    off = self.work_offsets_mm.get(st.work_offset, (0.0, 0.0, 0.0))
                    ca = float(v[la]) * scale + off[ia]
                    cb = float(v[lb]) * scale + off[ib]
                else:
                    ca = a0 + float(v.get(la, "0")) * scale
                    cb = b0 + float(v.get(lb, "0")) * scale
                check_radius(a0, b0, a1, b1, ca, cb, tol)
            else:
                raise ValueError(f"arc needs its centre ({la}, {lb}) or a radius R")
        except ValueError as exc:
            which = "R" if has_r else (la if la in v else lb if lb in v else 0)
            raise self._fail(raw, which, str(exc), line) from None
        c = [0.0, 0.0, 0.0]
        c[ia], c[ib], c[ic] = ca, cb, p0[ic]
        return c[0], c[1], c[2]
