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
from planning.nc._blocks import Blocks
from planning.nc._codes import FAST_LETTERS, INCH_MM, OFFSET_CODES
from planning.nc._context import Codes, Context, Sink, start_state
from planning.nc._cycles import Cycles
from planning.nc._fast import FastRuns
from planning.nc._modes import Modes
from planning.nc._moves import Moves
from planning.nc._settings import Settings
from planning.nc._words import WordRules
from planning.nc.errors import NCError, NCWarning
from planning.nc.motion import Motion, MotionBuilder
from planning.nc.state import ModalState

if TYPE_CHECKING:
    from analysis.config import MachineConfig

DEFAULT_ARC_TOLERANCE_MM = 0.002  # MachineConfig's default
NAN = math.nan
FAST_CHUNK = 65_536  # lines read at a time by run()
CHUNK_BLOCKS = 8_192  # streamed chunk: faster than 65,536 (cache), ~55 MB peak for 1 M blocks


class _NullSink:
    """Builder stand-in that drops segments (modal state only)."""

    class _Drop:
        def extend(self, _: object, /) -> None:
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

    Notes
    -----
    Built by composition: a :class:`~planning.nc._context.Context` (options, modal state,
    per-block scratch, error helpers) shared by its parts, which each take it explicitly: the
    words (:class:`~planning.nc._words.WordRules`), the modal codes
    (:class:`~planning.nc._modes.Modes`), the group-0 settings
    (:class:`~planning.nc._settings.Settings`), the moves (:class:`~planning.nc._moves.Moves`),
    the canned cycles (:class:`~planning.nc._cycles.Cycles`), the blocks other than a plain move
    that dispatch to the last three (:class:`~planning.nc._blocks.Blocks`) and the fast path
    (:class:`~planning.nc._fast.FastRuns`). The interpreter reads a block and dispatches.
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
        self.fast = bool(fast)
        if cutter_comp not in ("warn", "refuse"):
            raise ValueError(f"cutter_comp must be 'warn' or 'refuse', got {cutter_comp!r}")
        if probing not in ("allow", "refuse"):
            raise ValueError(f"probing must be 'allow' or 'refuse', got {probing!r}")
        name = dialect or (machine.dialect if machine is not None else dialects.DEFAULT)
        if name not in dialects.REGISTRY:
            raise NCError(
                f"dialect must be one of {', '.join(dialects.DIALECTS)}, got {name!r}",
                file=file,
            )
        self.dialect = name
        d = self.rules = dialects.get(name)
        self.block_delete = block_delete
        tol = arc_tolerance_mm
        if tol is None and machine is not None:
            # LinuxCNC has its own default: only a tolerance the machine file sets overrides it
            if not d.arc_spiral or "arc_radius_tolerance_mm" in machine.model_fields_set:
                tol = machine.arc_radius_tolerance_mm
        inf = math.inf
        self._ctx = ctx = Context(
            file=str(file), strict=strict, dialect=name, rules=d, g_group=d.g_groups(),
            known_m=d.m_codes,
            arc_tolerance_mm=DEFAULT_ARC_TOLERANCE_MM if tol is None else float(tol),
            spiral_tol_mm=None if tol is None else float(tol),  # LinuxCNC: None = its own
            peck_clearance_mm=float(
                d.peck_clearance_mm if peck_clearance_mm is None else peck_clearance_mm
            ),
            peck_default=peck_clearance_mm is None,
            feed_max_mm_min=machine.feed_max_mm_min if machine is not None else inf,
            spindle_max_rpm=machine.spindle_max_rpm if machine is not None else inf,
            cutter_comp=cutter_comp, probing=probing,
            state=start_state(machine, state, work_offsets_mm, reference_mm,
                              second_reference_mm),
        )  # fmt: skip
        self._refuses = bool(d.refused_g or d.refused_m or d.refused_letters)
        self._words = WordRules(ctx)
        self._modes = Modes(ctx, self._words)
        self._moves = Moves(ctx)
        self._blocks = Blocks(ctx, Settings(ctx), self._moves, Cycles(ctx, self._moves))
        self._fast_runs = FastRuns(ctx)
        self.blocks_seen = 0

    @property
    def state(self) -> ModalState:
        """The modal state after the blocks executed so far."""
        return self._ctx.state

    @state.setter
    def state(self, value: ModalState) -> None:
        self._ctx.state = value

    @property
    def warnings(self) -> list[NCWarning]:
        """What lenient mode skipped, and blocks ignored after the program end."""
        return self._ctx.warnings

    @property
    def strict(self) -> bool:
        """Unknown codes/letters and unused words raise (True) or become warnings (False)."""
        return self._ctx.strict

    @property
    def file(self) -> str:
        """The name used in error messages."""
        return self._ctx.file

    @property
    def _feed_max_mm_min(self) -> float:
        """The machine's feed limit (tests/test_nc_fastpath.py lowers it on an interpreter)."""
        return self._ctx.feed_max_mm_min

    @_feed_max_mm_min.setter
    def _feed_max_mm_min(self, value: float) -> None:
        self._ctx.feed_max_mm_min = value

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
    def _run(self, lines: Iterable[str], first_line: int, out: Sink) -> None:
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

    def _execute_lines(self, lines: list[str], block: int, out: MotionBuilder) -> None:
        """Execute ``lines`` (blocks ``block``, ``block + 1`` ...): runs of plain G0..G3 blocks
        at once when ``fast`` is on (:class:`~planning.nc._fast.FastRuns`), the others one by
        one."""
        if self.fast:
            self._fast_runs.execute_lines(lines, block, out, self._execute)
            return
        execute = self._execute
        for k, raw in enumerate(lines, block):
            execute(raw, k + 1, k, out)

    def _execute_safe(self, raw: str, line: int, block: int, out: MotionBuilder) -> None:
        saved = self.state.copy()
        try:
            self._execute(raw, line, block, out)
        except NCError:
            self.state = saved
            raise
        self.blocks_seen = block + 1

    def _execute(self, raw: str, line: int, block: int, out: Sink) -> None:
        ctx = self._ctx
        words, flag = _lexer.block_words(raw, ctx.file, line)
        st = ctx.state
        if flag:
            if flag == 2:
                st.tape_marks += 1
                return
            if self.block_delete:
                return
        if not words:
            return
        if st.ended or st.tape_marks >= 2:
            ctx.warnings.append(
                NCWarning(
                    "block after the program end (M2/M30 or closing %) is ignored",
                    ctx.file,
                    line,
                    1,
                    raw.strip()[:40],
                )
            )
            return
        st.stopped = False
        gcodes, mcodes, v = self._words.sort(raw, words, line)
        if self._refuses:
            self._words.refused(raw, words, gcodes, mcodes, line)
        self._execute_words(raw, line, block, out, gcodes, mcodes, v)

    def _execute_words(
        self, raw: str, line: int, block: int, out: Sink, gcodes: Codes | None,
        mcodes: Codes | None, v: dict[str, str],
    ) -> None:  # fmt: skip
        """A block's codes and words, in the order of execution."""
        ctx = self._ctx
        st = ctx.state
        # ---- G codes: modes first so this block's words use them
        ctx.inverse_f = NAN
        ctx.rotary_to = None  # A B C target of this block, deg (set by its A/B/C words)
        if gcodes is None:
            explicit_motion = dwell = g53 = False
            home = None
            scale = fscale = INCH_MM if st.inch else 1.0
        else:
            inch_before = st.inch
            explicit_motion, dwell, g53, home, path = self._modes.gcodes(raw, gcodes, line)
            scale = INCH_MM if st.inch else 1.0
            # LinuxCNC reads F before G20/G21 (its order of execution), the others after
            fscale = (
                scale if inch_before == st.inch or not ctx.rules.feed_before_units
                else INCH_MM / scale
            )  # fmt: skip
            if path is not None:
                self._modes.path_control(raw, v, scale, line, path)
        # ---- other words
        if not v.keys() <= FAST_LETTERS:
            self._words.words(raw, v, fscale, line, gcodes, mcodes)
        else:  # only X Y Z F N: the common block
            if "F" in v:
                self._words.feed(raw, v, fscale, line)
            if "N" in v:
                st.sequence_number = self._words.whole(raw, v, "N", line)
        # ---- M codes before motion (tool change, spindle, coolant)
        end = mcodes is not None and self._modes.mcodes(raw, mcodes, v, line)
        # ---- dwell (LinuxCNC: then the block's move, if it has one)
        if dwell:
            self._blocks.dwell(raw, v, line, block, out, explicit_motion)
        # ---- motion
        rotary = ctx.rotary_to is not None
        has_axes = ("X" in v or "Y" in v or "Z" in v or rotary) and (
            not dwell or ctx.rules.dwell_then_move
        )
        mode = st.motion
        if home is not None:
            self._blocks.group0(raw, v, scale, line, block, out, home, has_axes, explicit_motion)
        elif has_axes or (
            explicit_motion and mode >= 2 and mode <= 3 and ("I" in v or "J" in v or "K" in v)
        ):
            if mode >= 80:
                self._blocks.cycle(raw, v, scale, line, block, out, rotary)
            else:
                self._moves.move(raw, v, scale, line, block, out, mode, g53)
        elif g53:
            raise ctx.fail(raw, 0, "G53 needs an axis word (X, Y or Z)", line)
        if end:
            st.ended = True
