"""The NC interpreter: blocks of text in, canonical :class:`~planning.nc.Motion` segments out.

Two ways in:

* whole programs — :func:`interpret` (text, :class:`~planning.nc.Program` or lines) and
  :func:`interpret_file` (streams the file line by line; memory grows only with the segment
  arrays, so million-block programs are fine);
* one block at a time — :class:`Interpreter`: ``it.execute("G1 X10 F300")`` returns that block's
  segments as a (small) Motion and updates ``it.state`` (a :class:`~planning.nc.ModalState`, copy
  it with ``it.state.copy()``). The simulated controllers use this as blocks arrive over serial.

Semantics (RS-274 / Fanuc flavour by default; ``dialect`` "grbl" and "linuxcnc" change what is
listed below, "linuxcnc" follows LinuxCNC's interpreter ``rs274`` to the canonical move):

* Within a block: G-codes first (plane, units, distance modes, ...), then F S T, M6, M3/M4/M5,
  M7/M8/M9, dwell, motion, then M0/M1/M2/M30. Units switched in a block apply to that block's words
  (LinuxCNC: except F, which its order of execution reads before G20/G21, so ``G21 ... G20 F6``
  sets 6 mm/min; G94 always clears the feed there, as in LinuxCNC).
* Positions and feeds are converted to mm and mm/min; positions are in the machine frame, i.e.
  program coordinates plus the active work offset G54..G59 (LinuxCNC also G59.1..G59.3; zero
  unless ``work_offsets_mm`` is given or a G10 L2/L20 sets them) plus the G92 / G52 offset. G53
  moves to machine coordinates for one block.
* G10 L2 Pn (P1..P9 = G54..G59.3, P0 the active one; absolute values whatever G90/G91, as in
  LinuxCNC; Fanuc: G91 adds) sets a work offset, G10 L20 sets it so that the current position
  reads the given values. G10 L1/L10/L11 write the tool table (``state.tool_table``: recorded only,
  tool length is not applied). G92 makes the current position read the given values (the offset
  applies to every work offset), G92.1 cancels and forgets it, G92.2 cancels and keeps it, G92.3
  restores it; G52 sets it directly (a local offset). G10 R (rotation) is refused.
* GRBL and LinuxCNC: G43.1 sets a dynamic tool length offset from its axis words (GRBL: Z only;
  absolute whatever G91), G49 or G43 cancels it; the tool does not move, so the current position
  (program coordinates) changes by the offset's change, as rs274ngc's and GRBL's do. G38.2..G38.5
  are modal probe moves: a feed move to the target (where a probe stops depends on the part);
  errors as the controls': no feed, G93, cutter compensation on, a target within 0.254 mm
  (LinuxCNC) or at the start (GRBL); ``probing="refuse"`` raises (what the Z-map consumers ask).
* G61 / G61.1 / G64 (with P blending tolerance, Q naive-CAM tolerance) are recorded in the state:
  the motion is the programmed path in every mode.
* G40/G41/G42 (with D) and G43/G49 (with H) are recorded in the state; the motion is the
  programmed tool-tip path (no cutter or length compensation applied). A G41/G42 gives a warning
  (the path is not the tool centre's), or an error with ``cutter_comp="refuse"`` (what the Z-map
  consumers ask for: they would cut the wrong path).
* A/B/C words move the rotary axes (degrees; G90 absolute, G91 incremental; no unit or offset
  conversion) together with X/Y/Z in a G0/G1/G2/G3 block: Motion carries each segment's rotary
  start and end. Under G94 the feed F applies to the combined move (mm and degrees together, as
  on Fanuc; LinuxCNC: see G93 below); under G93 the move takes 1/F min whatever its axes. A/B/C
  in a dwell, reference return (LinuxCNC: allowed, the rotary axes return too) or canned-cycle
  block are errors.
* G80..G83 with G98/G99 expand to rapid/feed/dwell moves (:mod:`planning.nc.canned`), drilling
  along the normal of the plane (Z in G17, Y in G18, X in G19); LinuxCNC's own rules (positioning
  at the clearance level, 0.254 mm G83 re-entry, R/Z/P/Q required when a cycle starts) there.
* G28 / G30 (return to the reference / second reference point, P2 only), as on Fanuc: the axes
  named rapid to the intermediate point their words give (program coordinates, G90 or G91; ``G91
  G28 Z0`` goes straight up), then to the reference point, which is in machine coordinates (the
  work offset does not apply, as with G53). Axes not named do not move. The points come from the
  machine config (``reference_point_mm`` / ``second_reference_point_mm``) or the
  ``reference_mm`` / ``second_reference_mm`` options; with neither, machine zero = work zero
  (0, 0, 0) is used and a warning says so. GRBL and LinuxCNC: a G28/G30 with no axis word moves
  all axes straight to the point (Fanuc: an error; LinuxCNC: the rotary axes too, to 0 degrees
  unless stored); G28.1 / G30.1 store the current position as the point. Tool length
  compensation is not applied, so the point is where the programmed tool tip goes.
* G29 (Fanuc; GRBL and LinuxCNC have none): the named axes rapid to the intermediate point of
  the last G28/G30 that named them, then to the programmed point (G91: relative to the
  intermediate point).
* G93 inverse-time feed: every feed move (G1/G2/G3) needs its own F, and takes 1/F minutes; the
  Motion gets ``feed_mm_min = path length * F``. LinuxCNC: under G94 F is along X Y Z when they
  move (the rotary axes follow), in degrees/min for a rotary-only move; the Motion's feed is
  scaled so that the time along the combined travel is LinuxCNC's. F is not modal under G93, and
  switching between G93 and G94 leaves no feed set (program F again), as in RS-274/NGC. Canned
  cycles and feed moves with no travel at all under G93 are errors (LinuxCNC: the latter take no
  time; its G93 rate is at least 0.1 units/min, which slows very short moves).
* Arc radius tolerance: the machine's ``arc_radius_tolerance_mm`` (default 0.002 mm) for Fanuc
  and GRBL; LinuxCNC's rule for "linuxcnc" (:func:`planning.nc.arcs.check_radius_linuxcnc`: I/J/K
  end radius within 0.0283 mm / 0.00283 in, or within 0.1 % up to 100 times that, the arc then
  being a spiral from start to end; R arcs whose chord exceeds 2R by 0.00127 mm at most).
  LinuxCNC's ``G2/G3 P``: P turns, as P - 1 full circles (segments whose start and end coincide
  in the plane) and then the arc, the helix spread evenly over the whole angle.
* LinuxCNC also knows M48/M49 and M50-M53 (overrides), M60 (pallet stop: like M0), M61 Q (the
  tool in the spindle is Q, no change), M62-M65 (digital outputs), G8 and G97 (the only lathe
  radius and spindle modes there are): none changes the motion.
* G4 / G82 ``P``: milliseconds on Fanuc, seconds on GRBL and LinuxCNC (which takes no ``G4 X``).
* GRBL dialect: what GRBL 1.1 answers ``error:20`` to (G41/G42, G43, G81-G83, G98/G99, G90.1,
  G52, G64, G10 other than L2/L20, M6, O D H Q and A/B/C words) is an error (lenient: a
  warning), so ``dnc send`` refuses it before anything is sent.
* After M2/M30 or the closing ``%`` nothing more is executed; blocks with words there give a
  warning.
* Strict mode (default) raises :class:`~planning.nc.NCError` for unknown G/M codes, unknown
  letters and words no code uses; lenient mode records them as
  :class:`~planning.nc.NCWarning` in ``warnings`` and goes on. Errors that leave the motion
  unknown (bad arcs, feed move with no F, ...) raise in both modes.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Iterator, Mapping, Sequence
from typing import TYPE_CHECKING

from planning.nc import _lexer, dialects
from planning.nc._codes import (
    FAST_LETTERS,
    INCH_MM,
    LETTERS_GM,
    OFFSET_CODES,
    OFFSET_INDEX,
    gkey,
    gname,
)
from planning.nc._fast import FastRuns
from planning.nc._modes import Modes
from planning.nc._words import WordRules
from planning.nc.errors import NCError, NCWarning
from planning.nc.motion import Motion, MotionBuilder
from planning.nc.state import ModalState

if TYPE_CHECKING:
    from analysis.config import MachineConfig

DEFAULT_ARC_TOLERANCE_MM = 0.002  # MachineConfig's default
NAN = math.nan
# codes that set something from the block's words (no motion): G10, G28.1, G30.1, G43.1 (group
# 8), G52, G92, G92.1, G92.2, G92.3
SETTING_CODES = frozenset({100, 281, 301, 431, 520, 920, 921, 922, 923})
HOME_CODES = frozenset({280, 290, 300})
FAST_CHUNK = 65_536  # lines read at a time by run()
CHUNK_BLOCKS = 8_192  # streamed chunk: faster than 65,536 (cache), ~55 MB peak for 1 M blocks


class _NullSink:
    """Builder stand-in that drops segments (modal state only)."""

    class _Drop:
        def extend(self, _: object) -> None:
            pass

    fbuf = ibuf = _Drop()


class Interpreter(FastRuns, WordRules, Modes):
    """Executes NC blocks one at a time, tracking all modal state.

    Parameters
    ----------
    machine : MachineConfig, optional
        Gives the arc radius tolerance and the dialect (else 0.002 mm and ``"fanuc"``).
    strict : bool
        Unknown codes/letters and unused words raise (True) or become warnings (False).
    file : str
        Name used in error messages.
    dialect : str, optional
        A name of :data:`planning.nc.dialects.REGISTRY` (fanuc, grbl, linuxcnc ...); overrides
        the machine's (see the module docstring and :mod:`planning.nc.dialects` for what it
        changes). ``rules`` is its :class:`~planning.nc.dialects.Dialect`.
    block_delete : bool
        The block-delete switch: True skips blocks starting with ``/``.
    arc_tolerance_mm : float, optional
        Overrides the machine's arc radius tolerance, mm (LinuxCNC: its absolute spiral
        tolerance, the INI's ``CENTER_ARC_RADIUS_TOLERANCE_MM``; default LinuxCNC's).
    work_offsets_mm : mapping {54..59, 59.1..59.3: (x, y, z)}, optional
        Work offsets added to program coordinates; default all zero (G10 L2/L20 can set them).
    peck_clearance_mm : float, optional
        G83 re-entry clearance above the previous peck, mm (default 0.1; LinuxCNC 0.254).
    reference_mm, second_reference_mm : (x, y, z), optional
        Machine coordinates of the G28 / G30 points, mm; override the machine's.
    state : ModalState, optional
        Start from this state (copied), e.g. to resume a program at a block.
    cutter_comp : {"warn", "refuse"}
        G41/G42 cutter radius compensation is not applied: warn once (default) or raise.
    probing : {"allow", "refuse"}
        G38.2..G38.5 probe moves are taken as reaching their target (default), or raise: where
        a probe stops depends on the part (what the Z-map consumers ask for).
    fast : bool
        :meth:`run` and :meth:`iter_chunks` execute runs of plain ``G0``..``G3`` blocks (only N
        G0..G3 X Y Z I J K R F words) vectorised, with the same result bit for bit (default); False
        executes every block on its own.

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
        work_offsets_mm: Mapping[int | float, Sequence[float]] | None = None,
        peck_clearance_mm: float | None = None,
        reference_mm: Sequence[float] | None = None,
        second_reference_mm: Sequence[float] | None = None,
        state: ModalState | None = None,
        cutter_comp: str = "warn",
        probing: str = "allow",
        fast: bool = True,
    ) -> None:
        self.strict = strict
        self.fast = bool(fast)
        if cutter_comp not in ("warn", "refuse"):
            raise ValueError(f"cutter_comp must be 'warn' or 'refuse', got {cutter_comp!r}")
        if probing not in ("allow", "refuse"):
            raise ValueError(f"probing must be 'allow' or 'refuse', got {probing!r}")
        self.cutter_comp = cutter_comp
        self.probing = probing
        self._comp_warned = False
        self.file = str(file)
        self.dialect = dialect or (machine.dialect if machine is not None else dialects.DEFAULT)
        if self.dialect not in dialects.REGISTRY:
            raise NCError(
                f"dialect must be one of {', '.join(dialects.DIALECTS)}, got {self.dialect!r}",
                file=file,
            )
        d = self.rules = dialects.get(self.dialect)
        self._g_group = d.g_groups()
        self._known_m = d.m_codes
        self._refuses = bool(d.refused_g or d.refused_m or d.refused_letters)
        self.block_delete = block_delete
        tol = arc_tolerance_mm
        if tol is None and machine is not None:
            # LinuxCNC has its own default: only a tolerance the machine file sets overrides it
            if not d.arc_spiral or "arc_radius_tolerance_mm" in machine.model_fields_set:
                tol = machine.arc_radius_tolerance_mm
        self._spiral_tol_mm = None if tol is None else float(tol)  # LinuxCNC: None = its own
        self.arc_tolerance_mm = DEFAULT_ARC_TOLERANCE_MM if tol is None else float(tol)
        self._peck_default = peck_clearance_mm is None
        if peck_clearance_mm is None:
            peck_clearance_mm = d.peck_clearance_mm
        self.peck_clearance_mm = float(peck_clearance_mm)
        if reference_mm is None and machine is not None:
            reference_mm = machine.reference_point_mm
        if second_reference_mm is None and machine is not None:
            second_reference_mm = machine.second_reference_point_mm
        self._reference_warned = False
        self._inverse_f = NAN  # this block's F under G93 (1/min)
        inf = math.inf
        self._feed_max_mm_min = machine.feed_max_mm_min if machine is not None else inf
        self._spindle_max_rpm = machine.spindle_max_rpm if machine is not None else inf
        st = self.state = state.copy() if state is not None else ModalState()
        if work_offsets_mm:
            table = list(st.work_offsets_mm)
            for code, off in work_offsets_mm.items():
                key = round(float(code) * 10.0)
                if key not in OFFSET_INDEX:
                    raise ValueError(f"work_offsets_mm: no work offset G{code}")
                table[OFFSET_INDEX[key]] = (float(off[0]), float(off[1]), float(off[2]))
            st.work_offsets_mm = tuple(table)
        # None: machine zero = work zero, said once in a warning when a G28/G30 needs it
        if reference_mm is not None and (state is None or st.reference_mm is None):
            st.reference_mm = _point(reference_mm)
        second = second_reference_mm if second_reference_mm is not None else reference_mm
        if second is not None and (state is None or st.second_reference_mm is None):
            st.second_reference_mm = _point(second)
        self._set_origin()
        self.warnings: list[NCWarning] = []
        self.blocks_seen = 0

    @property
    def work_offsets_mm(self) -> dict[int | float, tuple[float, float, float]]:
        """The work offsets in force, ``{54: (x, y, z), ..., 59.3: ...}`` mm (G10 may have set
        them; the G92 offset is not included: see ``state.origin_mm``)."""
        return dict(zip(OFFSET_CODES, self.state.work_offsets_mm))

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

    def iter_chunks(
        self, lines: Iterable[str], *, chunk_blocks: int = CHUNK_BLOCKS, first_line: int = 1
    ) -> Iterator[Motion]:
        """Execute many blocks as :meth:`run` does, yielding their segments chunk by chunk: one
        Motion per ``chunk_blocks`` blocks (empty chunks are not yielded), so memory is bounded
        by the chunk, not the program. ``blocks_seen`` is up to date after each chunk."""
        if chunk_blocks < 1:
            raise ValueError(f"chunk_blocks must be >= 1, got {chunk_blocks}")
        block = first_line - 1
        it = iter(lines)
        while True:
            out = MotionBuilder()
            chunk = list(itertools.islice(it, chunk_blocks))
            self._execute_lines(chunk, block, out)
            block += len(chunk)
            self.blocks_seen = block
            if len(out.ibuf):
                yield out.build()
            if len(chunk) < chunk_blocks:
                return

    def skip(self, lines: Iterable[str], *, first_line: int = 1) -> None:
        """Execute blocks for their modal effect only (no segments are kept)."""
        self._run(lines, first_line, _NullSink())

    # ------------------------------------------------------------------ internals
    def _run(self, lines: Iterable[str], first_line: int, out: MotionBuilder | _NullSink) -> None:
        block = first_line - 1
        if self.fast and isinstance(out, MotionBuilder):
            it = iter(lines)
            while chunk := list(itertools.islice(it, FAST_CHUNK)):
                self._execute_lines(chunk, block, out)
                block += len(chunk)
            self.blocks_seen = block
            return
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

    def _refused_words(self, raw: str, words, gcodes, mcodes, line: int) -> None:
        """What the control refuses outright (GRBL 1.1's error:20): say so before anything is
        sent."""
        d = self.rules
        for key, k in gcodes or ():
            if key in d.refused_g:
                self._problem(raw, k, f"{gname(key)} is not a {d.refusal_name} command", line)
        for key, k in mcodes or ():
            if key // 10 in d.refused_m:
                self._problem(raw, k, f"M{key // 10} is not a {d.refusal_name} command", line)
        # a line holding only an O program number (and N) is not sent: the GRBL sender strips
        # it (planning.nc.grbl.grbl_send_text), as ``nc check --dialect grbl`` reads it
        lone_o = d.strips_lone_o and [ltr for ltr, _ in words if ltr != "N"] == ["O"]
        for k, (letter, _) in enumerate(words):
            if letter in d.refused_letters and not lone_o:
                self._problem(raw, k, f"{d.refusal_name} has no {letter} word", line)

    def _set_origin(self) -> None:
        """``state.origin_mm`` from the active work offset and the G92 offset."""
        st = self.state
        w = st.work_offsets_mm[st.work_offset_index]
        g = st.g92_offset_mm
        st.origin_mm = (w[0] + g[0], w[1] + g[1], w[2] + g[2])

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
                if key not in self._g_group:
                    v = None  # let the slow path report it
                else:
                    gcodes = [(key, words.index(("G", g)))]
            m = v.pop("M", None) if v is not None else None
            if m is not None:
                key = round(float(m) * 10.0)
                if key % 10 or key // 10 not in self._known_m:
                    v = None
                else:
                    mcodes = [(key, words.index(("M", m)))]
        else:
            v = None
        if v is None:
            gcodes, mcodes, v = self._sort_words(raw, words, line)
        if self._refuses:
            self._refused_words(raw, words, gcodes, mcodes, line)

        # ---- G codes: modes first so this block's words use them
        self._inverse_f = NAN
        self._rotary_to = None  # A B C target of this block, deg (set by its A/B/C words)
        if gcodes is None:
            explicit_motion = dwell = g53 = False
            home = None
            scale = fscale = INCH_MM if st.inch else 1.0
        else:
            inch_before = st.inch
            explicit_motion, dwell, g53, home, path = self._gcodes(raw, gcodes, line)
            scale = INCH_MM if st.inch else 1.0
            # LinuxCNC reads F before G20/G21 (its order of execution), the others after
            fscale = (
                scale if inch_before == st.inch or not self.rules.feed_before_units
                else INCH_MM / scale
            )  # fmt: skip
            if path is not None:
                self._path_control(raw, v, scale, line, path)
        # ---- other words
        if not v.keys() <= FAST_LETTERS:
            self._words(raw, v, scale, fscale, line, gcodes, mcodes)
        else:  # only X Y Z F N: the common block
            if "F" in v:
                self._feed(raw, v, fscale, line)
            if "N" in v:
                st.sequence_number = self._whole(raw, v, "N", line)

        # ---- M codes before motion (tool change, spindle, coolant)
        end = mcodes is not None and self._mcodes(raw, mcodes, v, line)

        # ---- dwell (LinuxCNC: then the block's move, if it has one)
        if dwell:
            self._dwell_block(raw, v, line, block, out, explicit_motion)

        # ---- motion
        rotary = self._rotary_to is not None
        has_axes = ("X" in v or "Y" in v or "Z" in v or rotary) and (
            not dwell or self.rules.dwell_then_move
        )
        mode = st.motion
        if home is not None:
            self._group0(raw, v, scale, line, block, out, home, has_axes, explicit_motion)
        elif has_axes or (
            explicit_motion and mode >= 2 and mode <= 3 and ("I" in v or "J" in v or "K" in v)
        ):
            if mode >= 80:
                self._cycle_block(raw, v, scale, line, block, out, rotary)
            else:
                self._move(raw, v, scale, line, block, out, mode, g53)
        elif g53:
            raise self._fail(raw, 0, "G53 needs an axis word (X, Y or Z)", line)
        if end:
            st.ended = True

    def _dwell_block(self, raw, v, line: int, block: int, out, explicit_motion: bool) -> None:
        """G4: the dwell (Fanuc / GRBL: alone; LinuxCNC: before the block's move)."""
        if self.rules.dwell_then_move:
            if explicit_motion and self.state.motion in (2, 3):
                raise self._fail(raw, "P", "G4 and G2/G3 cannot share a block (both use P)", line)
        else:
            if "A" in v or "B" in v or "C" in v:
                raise self._fail(
                    raw, next(L for L in "ABC" if L in v), "A/B/C words cannot move in a G4 "
                    "block (program the rotary move in its own G0/G1 block)", line,
                )  # fmt: skip
            if "Y" in v or "Z" in v or ("X" in v and "P" in v):
                raise self._fail(
                    raw,
                    next(L for L in "YZX" if L in v),
                    "G4 dwell cannot share its block with a move",
                    line,
                )
        self._dwell(raw, v, line, block, out)

    def _group0(self, raw, v, scale, line, block, out, home, has_axes, explicit_motion) -> None:
        """A block with G10, G28, G28.1, G29, G30, G30.1, G52 or a G92 code."""
        key, k = home
        mode = self.state.motion
        if key in SETTING_CODES:
            if has_axes and explicit_motion and mode != 80:
                raise _lexer.word_error(
                    raw, k, f"{gname(key)} and G{mode} both use the axis words and cannot "
                    "share a block", self.file, line,
                )  # fmt: skip
            self._setting(raw, v, scale, line, key, k)
            return
        if self._rotary_to is not None and not (self.rules.home_rotary and key != 290):
            raise self._fail(
                raw, next(L for L in "ABC" if L in v), f"A/B/C words cannot move in a "
                f"{gname(key)} block (program the rotary move in its own G0/G1 block)", line,
            )  # fmt: skip
        if explicit_motion and mode >= 81:
            raise _lexer.word_error(
                raw, k, f"{gname(key)} and G{mode} cannot share a block", self.file, line
            )
        self._home(raw, v, scale, line, block, out, key, k)

    def _cycle_block(self, raw, v, scale, line: int, block: int, out, rotary: bool) -> None:
        """A block with axis words under G80 (an error) or a canned cycle."""
        mode = self.state.motion
        if rotary:
            raise self._fail(
                raw, next(L for L in "ABC" if L in v), f"A/B/C words cannot move in a G{mode} "
                "block (program the rotary move in its own G0/G1 block)", line,
            )  # fmt: skip
        if mode == 80:
            raise self._fail(
                raw,
                next(L for L in "XYZABC" if L in v),
                "axis word with no motion mode in force (G80 cancelled it; program G0/G1)",
                line,
            )
        self._canned(raw, v, scale, line, block, out)


def _point(p: Sequence[float]) -> tuple[float, float, float]:
    return (float(p[0]), float(p[1]), float(p[2]))
