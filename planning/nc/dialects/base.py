"""What a controller dialect is: :class:`Dialect`, the rules one controller reads and writes NC by.

A dialect holds three kinds of rules, each asked by name where the rule applies (no code outside
this package compares dialect names):

* interpretation (:mod:`planning.nc.interpreter`): the codes it knows, the order of execution
  (units of F after G20/G21), the G10 forms, the arc radius rule, dwell units, what a G28 with
  no axis word does, what it refuses outright (GRBL's ``error:20``);
* line answers (:class:`LineRules`, :mod:`planning.nc.dialect`): what the control answers to a
  line as written (line length, comments, program and sequence numbers, codes of other
  controls), listed by ``cutlab nc check --dialect``;
* output (:class:`PostRules`, :mod:`planning.nc.output`): what the posts write for it (the ``%``
  wrapping and end, O and N words, decimal points, comments, dwell words, tool changes, what is
  expanded into G0/G1 moves).

And ``protocol``: how ``rig.dnc`` streams to it (None: the control reads files, no streamer).

A new controller is one module in this package with one ``DIALECT`` and its entry in
:data:`planning.nc.dialects.REGISTRY`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import NamedTuple

from planning.nc._codes import COMMON_G, COMMON_M, G_GROUP


class Answer(NamedTuple):
    """What a control answers to a line (``answer``: ``alarm``, ``error``, ``runs it`` ...), why,
    and whether it refuses the line (``"error"``) or runs it with a difference (``"warning"``)."""

    answer: str
    reason: str
    severity: str = "error"


@dataclass(frozen=True)
class LineRules:
    """The line-by-line answers of a control that reads ISO code (Fanuc, LinuxCNC, Mach3) as
    :func:`planning.nc.dialect.check_dialect` lists them; GRBL's come from its firmware model
    (:attr:`Dialect.firmware_model`) instead."""

    #: characters a line may have (None: no limit worth checking)
    max_line_chars: int | None = None
    #: a ``;`` comment (None: a comment like any other)
    semicolon: Answer | None = None
    #: a lower-case address letter (None: read as upper case)
    lower_case: Answer | None = None
    #: G words (as written: ``G28.1``) the control refuses, with its answer
    refused_g: Mapping[str, Answer] = field(default_factory=dict)
    #: M numbers the control refuses, with its answer
    refused_m: Mapping[int, Answer] = field(default_factory=dict)
    #: any O word (None: a program number, checked against ``program_number_max``)
    o_word: Answer | None = None
    program_number_max: int | None = None  # O1..O9999 on a Fanuc
    sequence_number_max: int | None = None  # N1..N99999 on a Fanuc
    #: a length word without a decimal point is read in least increments (Fanuc without DPI)
    least_increments: bool = False
    #: G4 X (None: X is a dwell time there)
    dwell_x: Answer | None = None
    #: a G4 P of this many seconds or more is worth a warning (P is seconds there)
    dwell_p_warn_s: float | None = None


@dataclass(frozen=True)
class PostRules:
    """What :func:`planning.nc.output.for_dialect` writes for the control."""

    #: ``%`` lines, O and blocks after the end kept as they are (else left out)
    keeps_tape: bool = False
    #: ``%`` on the first and last line (LinuxCNC's wrapping)
    wraps_percent: bool = False
    #: M30 appended when the program has no M2/M30
    appends_m30: bool = False
    #: ISO tape code: upper-case words, a decimal point in every length and angle word
    iso_words: bool = False
    #: ``;`` comments written as ``( )`` comments
    paren_comments: bool = False
    #: G80 kept in a block that names another motion code (else left out: one modal group)
    g80_with_motion: bool = False
    #: G29 written as it is (else expanded into G0 moves)
    g29: bool = False
    #: G90.1 absolute arc centres (else the centres are written relative to the arc's start)
    absolute_arc_centres: bool = True
    #: G91.1 is a code there (GRBL: G90.1 becomes G91.1; Fanuc: neither is written)
    g91_1: bool = True
    #: canned cycles written as cycles when the source reads them alike (else always expanded)
    canned_cycles: bool = True
    #: blank lines and block-delete blocks left out (GRBL ignores the '/': they would run)
    drops_blank_and_deleted: bool = False
    #: the word a dwell is written with: "X" (seconds) or "P" (the dialect's P units)
    dwell_word: str = "P"
    #: M6, G43/H, D, G64 and A/B/C are written (else: M6 -> M0 pause unless a tool changer, the
    #: others left out or refused; GRBL 1.1)
    full_words: bool = True
    #: the written program is also run through the firmware model's line checks (GRBL)
    firmware_check: bool = False


@dataclass(frozen=True)
class Dialect:
    """One controller's rules (see the module docstring)."""

    name: str  # the name the machine configs and ``--dialect`` use
    title: str  # how messages name the control: "LinuxCNC"
    #: ``rig.dnc`` streaming protocol (None: the control reads files)
    protocol: str | None
    #: G codes it knows (keys: ten times the number, see :mod:`planning.nc._codes`)
    g_codes: frozenset[int] = COMMON_G
    #: M codes it knows
    m_codes: frozenset[int] = COMMON_M

    # -- what it refuses although the interpreter knows it (an error, lenient: a warning)
    refused_g: frozenset[int] = frozenset()
    refused_m: frozenset[int] = frozenset()
    refused_letters: frozenset[str] = frozenset()
    refusal_name: str = ""  # "GRBL 1.1": how the refusals name the control
    #: a line holding only an O number (and N) is not refused (the sender strips it)
    strips_lone_o: bool = False
    #: codes it knows but answers with an error when they run: key -> message
    code_errors: Mapping[int, str] = field(default_factory=dict)
    #: G41/G42 cutter radius compensation exists there
    cutter_comp: bool = True

    # -- order of execution, units
    #: F is read before G20/G21 in the same block (so it is in the old units)
    feed_before_units: bool = False
    #: G94 always clears the feed (not only when the feed mode changes)
    g94_clears_feed: bool = False

    # -- dwells
    dwell_p_ms: bool = False  # G4 / G82 P in milliseconds (else seconds)
    dwell_x: bool = True  # G4 X (seconds) is a dwell
    dwell_then_move: bool = False  # G4 and a move share a block: the dwell, then the move

    # -- G28 / G30, G10, G43.1, G53, G38.x
    home_all_axes: bool = True  # G28/G30 with no axis word: all axes (else an error)
    home_rotary: bool = False  # A/B/C words in G28/G30, the rotary axes return too
    g10_l: tuple[int, ...] = (2, 20)  # the G10 L forms, in the order the error lists them
    g10_p_range: tuple[int, int] = (0, 6)  # G10 L2/L20 P (0: the active system)
    g10_incremental: bool = False  # G10 L2 values add under G91 (else absolute)
    g10_tool_table: bool = True  # G10 L1/L10/L11 write the tool table (else not modelled)
    g43_1_z_only: bool = False  # G43.1 takes Z and only Z
    g53_needs_absolute: bool = False  # G53 in G91 is an error
    probe_min_mm: float = 0.0  # a G38.x target this close to the start is an error

    # -- arcs, feeds, canned cycles
    #: LinuxCNC's radius rule (a spiral within its tolerance, its own default tolerance) instead
    #: of the machine's arc_radius_tolerance_mm on the end radius
    arc_spiral: bool = False
    arc_turns_p: bool = False  # G2/G3 P: turns
    #: G94 F along X Y Z when they move (the rotary axes follow), degrees/min for a rotary-only
    #: move; G93's rate at least 0.1 units/min (LinuxCNC)
    feed_along_xyz: bool = False
    #: canned cycles as rs274ngc runs them (positioning at the clearance level, R/Z/P/Q needed
    #: when a cycle starts, L >= 1)
    cycles_rs274ngc: bool = False
    peck_clearance_mm: float = 0.1  # G83 re-entry above the previous peck

    # -- line answers, output, firmware
    lines: LineRules = field(default_factory=LineRules)
    post: PostRules = field(default_factory=PostRules)
    #: lines are checked by the GRBL 1.1h firmware model (planning.nc.grbl), not LineRules
    firmware_model: bool = False
    #: the longest line the control reads (the posts keep within it; None: no limit)
    max_line_chars: int | None = None

    def g_groups(self) -> dict[int, int]:
        """The G-code -> modal group table of this dialect (its own codes only)."""
        return {k: g for k, g in G_GROUP.items() if k in self.g_codes}

    def dwell_seconds(self, p: float) -> float:
        """The dwell a G4 / G82 P word gives, s."""
        return p / 1000.0 if self.dwell_p_ms else p
