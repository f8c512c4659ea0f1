"""Restart from block N: the safe preamble sent before block N, and the blocks made complete.

The modal state in force just before block N is worked out by running ``planning.nc``'s
interpreter over blocks 0..N-1 (nothing is sent for them); :func:`planning.nc.restart_preamble`
writes it back as NC. What the preamble restores, in this order:

1. a comment ``(RESTART AT BLOCK N LINE L)`` (the GRBL streamer does not send comments);
2. units G20/G21, plane G17/G18/G19, arc centre mode G90.1/G91.1, feed mode G94, work offset
   G54..G59, and G40 G49 G98/G99 G80 (compensation off, canned cycle cancelled);
3. the tool in the spindle (``T.. M6``) and the next tool selected (``T..``);
4. spindle speed and direction (``S.. M3/M4/M5``), coolant (M8 or M9);
5. the approach (:func:`approach_for`): ``G90 G0 Z<clearance>``, then ``X.. Y..`` of the
   position before block N at that height, then down to its Z at the program's plunge feed
   (``G1 Z.. F<plunge>``, then ``F..`` restores the program's feed), so the tool never rapids
   below the clearance. The clearance is ``safe_z_mm`` (``--safe-z``) if given, else the highest
   Z of the program's rapids before block N, else the canned cycle's R plane; none of these: the
   restart is refused (give ``--safe-z``). The plunge feed is block N's own if it descends in Z,
   else that of the program's last Z-descending feed move before N, else ``plunge_feed_mm_min``
   (``--plunge-feed``, which also overrides the program's); none and a descent is needed:
   refused. :attr:`RestartPlan.notes` says which was used;
6. cutter compensation G41/G42 with D, tool length G43 with H, if they were on;
7. distance mode G90/G91 and the motion mode G0/G1, and the feed F.

Arcs and canned cycles (:func:`restart_plan`): a bare ``G2``/``G3`` or cycle code cannot set the
motion mode without moving (GRBL answers ``error:26``), so the preamble leaves it out and the
first block from N on that moves carries it:

- block N an arc: it is sent *complete*, from the interpreted geometry: ``G17 G90 G2 X.. Y.. Z..
  I.. J.. F..`` (plane, the program's distance mode, the motion code, every axis, the centre as
  the program's arc-centre mode wants it, the feed), whatever it leaned on before (modal G2, I/J
  relative to a start the preamble re-creates, incremental end point);
- a later block moving under a modal arc gets its ``G2``/``G3`` written in;
- inside a canned cycle (Fanuc; GRBL has none): the first hole block from N on is sent as a
  complete cycle block ``G98 G81 X.. Y.. Z.. R.. F..`` (Q for G83, P for G82), so it drills
  where the program did, from the return level the tool is left at. An incremental (G91) cycle
  is refused.

Positions and feeds are written with 4 decimals in the units in force: exact to 0.1 um in mm,
to the control's 0.0001 in (at most 1.27 um off) in inch.

``safe_z_mm`` is in mm, machine frame (the program frame: the controllers here apply no work
offsets); a clearance below the position before block N is raised to that position.

Refused (a clear DncError, nothing sent): N past the end or after M2/M30; for GRBL, a state that
needs codes GRBL does not take (cutter compensation, G43). For GRBL the preamble leaves out what
GRBL rejects (G98/G99, G90.1, G64 and M6: the tool change is done by hand there; ``T..`` is kept).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from analysis.config import MachineConfig
from planning.nc import (
    ARC_CCW,
    ARC_CW,
    DWELL,
    INCH_MM,
    LINE,
    RAPID,
    Interpreter,
    ModalState,
    NCError,
    NumberStyle,
    interpret,
    restart_preamble,
)
from rig.dnc.errors import DncError
from rig.dnc.nc import modal_state_at, nc_text
from rig.dnc.program import Program
from rig.dnc.protocols import protocol_of

_MOTION = {0: "G0", 1: "G1", 2: "G2", 3: "G3"}
_MOTION_WORDS = {0.0, 1.0, 2.0, 3.0, 80.0, 81.0, 82.0, 83.0}
_COMMENT = re.compile(r"\([^)]*\)|;.*$")
_WORD = re.compile(r"([A-Za-z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")


def _words(text: str) -> list[tuple[str, str, str]]:
    """(upper-case letter, number text, the word as written) of a block, comments left out."""
    return [(m.group(1).upper(), m.group(2), m.group(0)) for m in _WORD.finditer(
        _COMMENT.sub(" ", text))]  # fmt: skip


@dataclass(frozen=True)
class RestartPlan:
    """What a restart at ``block`` sends: the ``preamble`` lines, then the program from
    ``block`` with the blocks of ``replaced`` (program block index -> text) sent instead."""

    block: int
    preamble: list[str] = field(default_factory=list)
    replaced: dict[int, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)  # where the clearance and plunge feed came from
    approach: Approach | None = None


@dataclass(frozen=True)
class Approach:
    """How a restart reaches the position before block N: rapid to ``clearance_mm`` (machine
    frame), X Y there, then down to ``z_mm`` at ``plunge_mm_min`` (None: no descent needed).
    ``*_from``: where each figure came from, for people."""

    clearance_mm: float
    clearance_from: str
    z_mm: float
    plunge_mm_min: float | None
    plunge_from: str

    def notes(self) -> list[str]:
        out = [f"clearance Z{_fmt(self.clearance_mm)} mm ({self.clearance_from})"]
        if self.plunge_mm_min is not None:
            out.append(f"plunge F{_fmt(self.plunge_mm_min)} mm/min ({self.plunge_from})")
        else:
            out.append(f"no plunge: the restart point (Z{_fmt(self.z_mm)}) is at the clearance")
        return out


_Z_TOL_MM = 1e-6


def approach_for(
    program: Program,
    block: int,
    state: ModalState,
    machine: MachineConfig | None = None,
    safe_z_mm: float | None = None,
    plunge_feed_mm_min: float | None = None,
) -> Approach:
    """The clearance and plunge feed of a restart at ``block`` (see the module doc); DncError
    when the program gives neither and the option is not given."""
    where = f"{program.name}: restart at block {block} (line {block + 1})"
    z = float(state.position_mm[2])
    try:
        m = interpret(nc_text(program.text), machine, file=program.name)
    except NCError as exc:
        raise DncError(f"{where}: {exc} (nothing was sent)") from None
    blk = np.asarray(m.block)
    kind = np.asarray(m.kind)
    start = np.asarray(m.start, float).reshape(-1, 3)
    end = np.asarray(m.end, float).reshape(-1, 3)
    before = blk < block
    if safe_z_mm is not None:
        clear, clear_from = float(safe_z_mm), "--safe-z"
    else:
        rap = np.flatnonzero(before & (kind == RAPID))
        r_plane = float(getattr(getattr(state, "canned", None), "r_mm", math.nan))
        if len(rap):
            i = int(rap[np.argmax(end[rap, 2])])
            clear = float(end[i, 2])
            clear_from = f"the highest rapid before block {block}: line {int(blk[i]) + 1}"
        elif math.isfinite(r_plane):
            clear, clear_from = r_plane, "the canned cycle's R plane"
        else:
            raise DncError(
                f"{where}: the program has no rapid move before that block to take a clearance "
                "height from; give --safe-z MM (machine Z to approach from; nothing was sent)"
            )
    if clear < z - _Z_TOL_MM:
        clear_from += f", raised to the restart point's Z{_fmt(z)}"
        clear = z
    if z > clear - _Z_TOL_MM:
        return Approach(clear, clear_from, z, None, "")
    feed_kinds = np.isin(kind, (int(LINE), int(ARC_CW), int(ARC_CCW)))
    down = feed_kinds & (end[:, 2] < start[:, 2] - _Z_TOL_MM)
    feed = np.asarray(m.feed_mm_min, float)
    own = np.flatnonzero(blk == block)
    if plunge_feed_mm_min is not None:
        plunge, plunge_from = float(plunge_feed_mm_min), "--plunge-feed"
    elif len(own) and down[own[0]] and math.isfinite(feed[own[0]]):
        plunge, plunge_from = float(feed[own[0]]), f"block {block}'s own plunge"
    else:
        prev = np.flatnonzero(before & down & np.isfinite(feed))
        if not len(prev):
            raise DncError(
                f"{where}: the approach descends from Z{_fmt(clear)} to Z{_fmt(z)} mm and the "
                "program has no Z-descending feed move before that block to take the plunge "
                "feed from; give --plunge-feed MM_PER_MIN (nothing was sent)"
            )
        i = int(prev[-1])
        plunge = float(feed[i])
        plunge_from = f"the last Z-descending feed move before it: line {int(blk[i]) + 1}"
    return Approach(clear, clear_from, z, plunge, plunge_from)


def restart_blocks(
    program: Program,
    block: int,
    protocol: str,
    machine: MachineConfig | None = None,
    safe_z_mm: float | None = None,
    plunge_feed_mm_min: float | None = None,
) -> list[str]:
    """The preamble blocks to send before ``program``'s block ``block`` (0-based). A restart
    in an arc or a canned cycle also changes a block of the program: use :func:`restart_plan`
    (what ``cutlab dnc send`` does)."""
    return restart_plan(program, block, protocol, machine, safe_z_mm, plunge_feed_mm_min).preamble


def restart_plan(
    program: Program,
    block: int,
    protocol: str,
    machine: MachineConfig | None = None,
    safe_z_mm: float | None = None,
    plunge_feed_mm_min: float | None = None,
) -> RestartPlan:
    """The preamble and the completed blocks for a restart at ``block`` (see the module doc)."""
    if block <= 0:
        return RestartPlan(block)
    state = modal_state_at(program.text, block, program.name, machine)
    where = f"{program.name}: restart at block {block} (line {block + 1})"
    if state.ended:
        raise DncError(f"{where}: the program ended (M2/M30) before that block")
    rules = protocol_of(protocol)
    if not rules.takes_compensation(state.cutter_comp, state.tool_length):
        raise DncError(
            f"{where}: needs G{state.cutter_comp}/G{state.tool_length} compensation, which "
            f"{rules.title} does not take"
        )
    cycle = state.motion >= 81
    if cycle and not state.absolute:
        raise DncError(
            f"{where}: inside an incremental (G91) canned cycle; restart at the block that "
            "starts the cycle (nothing was sent)"
        )
    pre_state = state.copy()
    if cycle:
        pre_state.motion = 80  # the preamble cancels it; the completed block starts it again
    try:  # refusals of the preamble itself (unknown reference point, G92 in force)
        pre = restart_preamble(pre_state, plunge_feed=True)
    except NCError as exc:
        raise DncError(f"{where}: {exc} (nothing was sent)") from None
    if plunge_feed_mm_min is not None and not (0 < plunge_feed_mm_min < math.inf):
        raise DncError(f"--plunge-feed = {plunge_feed_mm_min}: expected a feed > 0 mm/min")
    app = approach_for(program, block, state, machine, safe_z_mm, plunge_feed_mm_min)
    pre = _with_approach(pre, pre_state, app)
    replaced: dict[int, str] = {}
    if state.motion in (2, 3) or cycle:
        pre[-1] = _without_motion(pre[-1])
        replaced = _complete(program, block, state, protocol, machine, where)
    out = [f"(RESTART AT BLOCK {block} LINE {block + 1})"]
    for text in pre:
        if rules.preamble_drop is not None:
            text = " ".join(rules.preamble_drop.sub("", text).split())
        if text:
            out.append(text)
    return RestartPlan(block, out, replaced, app.notes(), app)


def _with_approach(pre: list[str], st: ModalState, app: Approach) -> list[str]:
    """``restart_preamble``'s lines with its approach (``G90 G0 Z<safe>``, X Y, down at the
    program's modal feed or at rapid) replaced by the clearance and plunge feed of ``app``."""
    fmt = NumberStyle().format
    scale = 1.0 / INCH_MM if st.inch else 1.0
    oz = float(st.origin_mm[2])
    up = next(i for i, t in enumerate(pre) if t.startswith("G90 G0") and " Z" in t)
    xy = next(i for i in range(up + 1, len(pre)) if pre[i].startswith("X"))
    end = xy + 1
    while end < len(pre) and (pre[end].startswith(("Z", "G1 Z", "F"))):
        end += 1  # the old descent: "G1 Z.. F..", or "Z.." and "F.."
    head = pre[up].rsplit(" Z", 1)[0]
    lines = [f"{head} Z{fmt((app.clearance_mm - oz) * scale)}", *pre[up + 1 : xy + 1]]
    feed = st.feed_mm_min
    restore = f"F{fmt(feed * scale)}" if math.isfinite(feed) else ""
    if app.plunge_mm_min is not None:
        plunge = f"F{fmt(app.plunge_mm_min * scale)}"
        lines.append(f"G1 Z{fmt((app.z_mm - oz) * scale)} {plunge}")
        if restore and restore != plunge:
            lines.append(restore)
    elif restore:
        lines.append(restore)
    tail = list(pre[end:])
    if app.plunge_mm_min is not None and st.motion == 0:
        tail[-1] += " G0"  # the plunge left G1 in force; the program was in G0
    return [*pre[:up], *lines, *tail]


def _without_motion(line: str) -> str:
    """The preamble's last line (``G90 G2`` / ``G91 G3 G93``) without its G2/G3/cycle code."""
    return " ".join(w for w in line.split() if w not in ("G2", "G3", "G80", "G81", "G82", "G83"))


def _explicit_motion(text: str) -> bool:
    return any(ltr == "G" and float(num) in _MOTION_WORDS for ltr, num, _ in _words(text))


def _complete(
    program: Program,
    block: int,
    state: object,
    protocol: str,
    machine: MachineConfig | None,
    where: str,
) -> dict[int, str]:
    """The first block from ``block`` on that moves, made to carry its motion mode."""
    dialect = protocol_of(protocol).dialect_name
    try:
        it = Interpreter(machine, dialect=dialect, state=state, file=program.name)  # type: ignore[arg-type]
    except NCError as exc:
        raise DncError(f"{where}: {exc}") from None
    lines = nc_text(program.text).splitlines()
    first = program.position_of(block)
    for b in program.blocks[first:]:
        before = it.state.copy()
        try:
            m = it.execute(lines[b.index], block=b.index)
        except NCError as exc:
            raise DncError(f"{where}: {exc} (nothing was sent)") from None
        kinds = np.asarray(m.kind)
        if not len(m) or (kinds == DWELL).all():
            if it.state.ended:
                break
            continue
        if before.motion >= 81:
            return {b.index: _cycle_text(b.text, before, protocol, where)}
        if _explicit_motion(b.text) and b.index != block:
            return {}
        arc = (kinds == ARC_CW) | (kinds == ARC_CCW)
        if b.index == block and arc.any() and not any(before.rotary_named or ""):
            return {b.index: _arc_text(m, it.state, b.text)}
        if before.motion in (2, 3) and not _explicit_motion(b.text):
            return {b.index: f"{_MOTION[before.motion]} {b.text}"}
        return {}
    return {}


def _fmt(v: float) -> str:
    return NumberStyle().format(v)


def _arc_text(m: object, st: object, original: str) -> str:
    """Block N's arc written complete from its interpreted geometry."""
    kinds = np.asarray(m.kind)  # type: ignore[attr-defined]
    idx = np.flatnonzero((kinds == ARC_CW) | (kinds == ARC_CCW))
    i0, i1 = int(idx[0]), int(idx[-1])
    start = np.asarray(m.start[i0], np.float64)  # type: ignore[attr-defined]
    end = np.asarray(m.end[len(kinds) - 1], np.float64)  # type: ignore[attr-defined]
    center = np.asarray(m.center[i0], np.float64)  # type: ignore[attr-defined]
    plane = int(m.plane[i0])  # type: ignore[attr-defined]
    code = "G2" if kinds[i0] == ARC_CW else "G3"
    scale = 1.0 / INCH_MM if st.inch else 1.0  # type: ignore[attr-defined]
    origin = np.asarray(getattr(st, "origin_mm", (0.0, 0.0, 0.0)), float)
    if st.absolute:  # type: ignore[attr-defined]
        tgt = (end - origin) * scale
        dist = "G90"
    else:
        tgt = (end - start) * scale
        dist = "G91"
    axes_of = {17: (0, 1), 18: (2, 0), 19: (1, 2)}[plane]
    if getattr(st, "arc_absolute", False):
        cvals = (center - origin) * scale
    else:
        cvals = (center - start) * scale
    letters = "IJK"
    cwords = " ".join(f"{letters[a]}{_fmt(cvals[a])}" for a in sorted(axes_of))
    xyz = " ".join(f"{a}{_fmt(v)}" for a, v in zip("XYZ", tgt))
    if getattr(st, "feed_mode", 94) == 93:
        fw = [w for ltr, _, w in _words(original) if ltr == "F"]
        feed = fw[0] if fw else ""
    else:
        f = float(st.feed_mm_min) * scale  # type: ignore[attr-defined]
        feed = f"F{_fmt(f)}" if math.isfinite(f) else ""
    _ = i1
    return " ".join(x for x in (f"G{plane}", dist, code, xyz, cwords, feed) if x)


def _cycle_text(text: str, st: object, protocol: str, where: str) -> str:
    """A hole block inside a canned cycle, written as a complete cycle block."""
    cy = st.canned  # type: ignore[attr-defined]
    mode = int(cy.mode or st.motion)  # type: ignore[attr-defined]
    scale = 1.0 / INCH_MM if st.inch else 1.0  # type: ignore[attr-defined]
    oz = float(getattr(st, "origin_mm", (0.0, 0.0, 0.0))[2])
    have = {ltr for ltr, _, _ in _words(text)}
    words = [("G98" if st.retract_initial else "G99"), f"G{mode}", text]  # type: ignore[attr-defined]
    if "Z" not in have and math.isfinite(cy.z_mm):
        words.append(f"Z{_fmt((cy.z_mm - oz) * scale)}")
    if "R" not in have and math.isfinite(cy.r_mm):
        words.append(f"R{_fmt((cy.r_mm - oz) * scale)}")
    if mode == 83 and "Q" not in have and math.isfinite(cy.q_mm):
        words.append(f"Q{_fmt(cy.q_mm * scale)}")
    if mode == 82 and "P" not in have and cy.dwell_s:
        p = cy.dwell_s * 1000.0 if protocol_of(protocol).dialect.dwell_p_ms else cy.dwell_s
        words.append(f"P{_fmt(p)}")
    f = float(st.feed_mm_min) * scale  # type: ignore[attr-defined]
    if "F" not in have and math.isfinite(f):
        words.append(f"F{_fmt(f)}")
    if not math.isfinite(cy.z_mm) or not math.isfinite(cy.r_mm):
        raise DncError(f"{where}: the canned cycle's Z or R is not known (nothing was sent)")
    return " ".join(words)
