"""Differential checking of cutlab's NC interpreter (dialect "linuxcnc") against LinuxCNC's own
standalone interpreter ``rs274`` (Debian package ``linuxcnc-uspace``): shared by
``tests/test_nc_rs274.py`` and ``bench/nc_vs_rs274.py``.

``rs274 -g FILE`` prints LinuxCNC's canonical calls. They are turned into segments in the frame of
cutlab's :class:`~planning.nc.Motion` (machine mm, the tool tip) by a small canon model written
here from the canonical interface, independently of cutlab's interpreter:

* numbers are in the length units in force when the call is made (``USE_LENGTH_UNITS``), as
  LinuxCNC's task canon (``emccanon.cc``) converts them: positions when they are printed,
  offsets (``SET_G5X_OFFSET``, ``SET_G92_OFFSET``) and feeds (``SET_FEED_RATE``) when set, so a
  feed set before a G20 in the same block stays in mm/min;
* the canonical positions are program coordinates: the machine position adds the G5x and G92
  offsets; the tool length offset (``USE_TOOL_LENGTH_OFFSET``) is *not* added, the segments being
  the tool tip's path as cutlab's are (``rs274`` is run with a tool table of zero lengths so the
  two agree where LinuxCNC uses the offset, e.g. G53 and G28);
* ``ARC_FEED(first_end, second_end, first_axis, second_axis, rotation, axis_end_point, a, b, c)``
  is in the plane's own axis order (XY: X Y about Z, XZ: Z X about Y, YZ: Y Z about X); a
  ``|rotation|`` above 1 adds full turns, which are split off as full-circle segments, as cutlab
  does;
* feeds are compared in cutlab's convention, the feed along the combined travel of the linear and
  rotary axes: LinuxCNC's F is along X Y Z when they move (more than 1e-7 program units), else
  in degrees/min (``SET_FEED_RATE`` is not converted for the rotary axes).

Both sides drop straight moves that go nowhere (LinuxCNC emits some cutlab does not, e.g. the
first leg of a G28 from the intermediate point, or a canned cycle's approach at the level it is
at). ``rs274`` prints 4 decimals in the program's units, so positions agree within 1e-4 mm or
half a unit of its last digit in inch programs (0.00127 mm), plus half a unit of the last
digit of each offset in the sum, in the units it was printed in.
"""

from __future__ import annotations

import logging
import math
import os
import random
import re
import signal
import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

RS274 = Path("/usr/bin/rs274")
INSTALL_HINT = "apt-get install linuxcnc-uspace"
INCH_MM = 25.4
POS_TOL_MM = 1e-4  # end points and centres (mm programs)
DWELL_TOL_S = 1e-4
FEED_RTOL = 1e-6
_TINY_UNITS = 1e-7  # LinuxCNC: an axis moves if it moves more than this (program units)
_CALL = re.compile(r"^\s*\d+\s+N\S*\s+([A-Z_0-9]+)\((.*)\)\s*$")
_PLANES = {"CANON_PLANE_XY": 17, "CANON_PLANE_XZ": 18, "CANON_PLANE_YZ": 19}
# plane -> indices (first, second, axis) of ARC_FEED's numbers in X Y Z
_ARC_AXES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}
# canonical calls that move the tool in ways this model does not follow
_UNSUPPORTED = {
    "RIGID_TAP",
    "NURBS_FEED",
    "NURBS_G5_FEED",
    "NURBS_G6_FEED",
    "SPLINE_FEED",
    "START_SPEED_FEED_SYNCH",
}
RAPID, LINE, ARC_CW, ARC_CCW, DWELL = 0, 1, 2, 3, 4
KIND_NAMES = ("rapid", "line", "arc_cw", "arc_ccw", "dwell")


@dataclass
class Seg:
    """One move in cutlab's frame (machine mm, tool tip); ``tol`` is the position tolerance."""

    kind: int
    start: tuple[float, float, float]
    end: tuple[float, float, float]
    center: tuple[float, float, float] = (math.nan, math.nan, math.nan)
    feed: float = math.nan  # mm/min along the combined travel
    dwell_s: float = 0.0
    rot0: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rot1: tuple[float, float, float] = (0.0, 0.0, 0.0)
    plane: int = 17
    line: int = 0  # source line (cutlab's side only: rs274 does not print it)
    tol: float = POS_TOL_MM
    feed_tol: float = 0.0  # besides FEED_RTOL: what rounded positions make of a derived feed
    start_tol: float = 0.0  # the tolerance of the start point (the segment before's end)


@dataclass
class Canon:
    """What ``rs274`` printed, as segments; ``error`` is its error message or ""."""

    segments: list[Seg] = field(default_factory=list)
    error: str = ""
    unsupported: str = ""  # a canonical call this model cannot follow (then nothing is compared)


@dataclass(frozen=True)
class Outcome:
    """The comparison of one program: ``agree`` or the first difference."""

    file: str
    agree: bool
    segments: int = 0
    line: int = 0
    field: str = ""
    ours: str = ""
    theirs: str = ""
    skipped: str = ""  # why the program was not compared

    def __str__(self) -> str:
        if self.skipped:
            return f"{self.file}: skipped: {self.skipped}"
        if self.agree:
            return f"{self.file}: agree ({self.segments} segments)"
        where = f"{self.file}:{self.line}" if self.line else self.file
        return f"{where}: {self.field}: ours {self.ours} vs rs274 {self.theirs}"


def available() -> bool:
    return RS274.exists()


def tool_table(path: Path, tools: int = 99) -> Path:
    """A tool table of tools 1..``tools`` with zero length (tip = controlled point)."""
    path.write_text("".join(f"T{t} P{t} D0.1 Z0 ;\n" for t in range(1, tools + 1)))
    return path


class RS274CutShort(RuntimeError):
    """``rs274`` ended without reaching the end of the program or an error of its own (killed, or
    cut short): its output says nothing about cutlab."""


_END_CALLS = ("PROGRAM_END(", "FINISH(")  # M2/M30, and a program closed by "%"
RS274_TRIES = 3
_log = logging.getLogger(__name__)


def rs274_ended(returncode: int, text: str) -> str:
    """Why an ``rs274 -g`` run did not run to its end ("" if it did): it ends with an end of
    program (``PROGRAM_END``, or ``FINISH`` after a closing "%") and status 0, or with its own
    error message and status 1. (Two rs274 at once used to end after 5 canonical calls, killed by
    SIGBUS: both truncate and map ``$HOME/.tool.mmap``; :func:`run_rs274` gives each its own.)"""
    calls = [ln for ln in text.splitlines() if _CALL.match(ln)]
    said = [ln for ln in text.splitlines() if ln.strip() and ln.strip() != "executing"
            and not _CALL.match(ln)]  # fmt: skip
    if returncode < 0:
        why = f"killed by {signal.Signals(-returncode).name}"
    elif returncode == 0 and any(c in ln for ln in calls for c in _END_CALLS):
        return ""
    elif returncode == 1 and said:
        return ""
    else:
        why = f"status {returncode}, no end of program and no error message"
    return f"{why} after {len(calls)} canonical calls"


def run_rs274(program: Path, timeout_s: float = 60.0, rs274: Path = RS274) -> str:
    """``rs274 -g`` on ``program`` (in a scratch folder that is also its $HOME, with a tool table
    of zero lengths); its stdout and stderr together. A run cut short (:func:`rs274_ended`) is
    tried again, up to :data:`RS274_TRIES` times, each reason logged; then
    :class:`RS274CutShort`."""
    reasons = []
    for attempt in range(1, RS274_TRIES + 1):
        with tempfile.TemporaryDirectory() as tmp:
            tbl = tool_table(Path(tmp) / "tools.tbl")
            proc = subprocess.run(
                [str(rs274), "-g", "-t", str(tbl), str(Path(program).resolve())],
                cwd=tmp,
                # rs274 creates, truncates and maps $HOME/.tool.mmap: a shared one is cut under
                # another run's feet (SIGBUS)
                env={**os.environ, "HOME": tmp},
                stdin=subprocess.DEVNULL,
                capture_output=True,
                text=True,
                timeout=timeout_s,
            )
        text = proc.stdout + proc.stderr
        why = rs274_ended(proc.returncode, text)
        if not why:
            return text
        reasons.append(f"try {attempt}: {why}")
        _log.warning("rs274 on %s was cut short (%s)", program, reasons[-1])
    raise RS274CutShort(
        f"rs274 was cut short on {program} ({'; '.join(reasons)}): "
        "its output says nothing about cutlab"
    )


def _nums(args: str) -> list[float]:
    return [float(x) for x in args.replace(" ", "").split(",") if x]


def parse_canon(text: str) -> Canon:
    """The segments of ``rs274 -g`` output (see the module docstring for the model)."""
    out = Canon()
    unit = 1.0  # mm per program unit
    g5x = [0.0] * 6
    g92 = [0.0] * 6
    plane = 17
    feed_lin = feed_ang = 0.0  # mm/min, deg/min
    pos = (0.0, 0.0, 0.0)
    rot = (0.0, 0.0, 0.0)
    g5x_round = g92_round = 0.0  # what the 4-decimal print of the offsets may be off, mm
    end_tol = 0.0  # the tolerance of the current position
    tlo = (0.0, 0.0, 0.0)  # the tool length offset, mm
    errors = []
    for raw in text.splitlines():
        m = _CALL.match(raw)
        if m is None:
            s = raw.strip()
            if s and s != "executing":
                errors.append(s)
            continue
        name, args = m.group(1), m.group(2)
        if name == "USE_LENGTH_UNITS":
            unit = INCH_MM if "INCH" in args else 10.0 if "CM" in args else 1.0
        elif name == "SET_G5X_OFFSET":
            g5x = [v * (unit if i < 3 else 1.0) for i, v in enumerate(_nums(args)[1:7])]
            g5x_round = 0.5e-4 * unit if any(g5x[:3]) else 0.0
        elif name == "SET_G92_OFFSET":
            g92 = [v * (unit if i < 3 else 1.0) for i, v in enumerate(_nums(args)[:6])]
            g92_round = 0.5e-4 * unit if any(g92[:3]) else 0.0
        elif name == "USE_TOOL_LENGTH_OFFSET":
            # the tool does not move: the current position (program coordinates) reads the
            # offset's change the other way (rs274ngc's current_z -= new - old)
            new = tuple(float(v) * unit for v in args.split(",")[0].split()[:3])
            pos = tuple(p - (n - o) for p, n, o in zip(pos, new, tlo))
            end_tol += 0.5e-4 * unit if any(new) else 0.0
            tlo = new
        elif name == "SET_XY_ROTATION":
            if _nums(args)[0] != 0.0:
                out.unsupported = out.unsupported or "SET_XY_ROTATION (G10 L2 R)"
        elif name == "SELECT_PLANE":
            plane = _PLANES.get(args.strip(), 0)
            if not plane:
                out.unsupported = out.unsupported or f"SELECT_PLANE({args})"
        elif name == "SET_FEED_RATE":
            f = _nums(args)[0]
            feed_lin, feed_ang = f * unit, f
        elif name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "STRAIGHT_PROBE", "ARC_FEED"):
            # (a probe: a feed to its target, where cutlab takes it to end; rs274's simulated
            # probe trips 0.254 mm short, which only moves that leave its axis out would show)
            tol = max(POS_TOL_MM, 0.5e-4 * unit + g5x_round + g92_round + 1e-9)
            n = _nums(args)
            if any(n[9 if name == "ARC_FEED" else 6 :]):
                out.unsupported = out.unsupported or f"{name} with U V W"
            if name == "ARC_FEED":
                segs = _arc(n, plane, unit, g5x, g92, pos, rot, feed_lin, tol, end_tol)
            else:
                end = tuple(n[i] * unit + g5x[i] + g92[i] for i in range(3))
                r1 = tuple(n[3 + i] + g5x[3 + i] + g92[3 + i] for i in range(3))
                seg = Seg(RAPID if name == "STRAIGHT_TRAVERSE" else LINE, pos, end, rot0=rot,
                          rot1=r1, plane=plane, tol=tol)  # fmt: skip
                if seg.kind == LINE:
                    tiny = max(_TINY_UNITS * unit, tol + end_tol)  # rounded ends move a hair
                    seg.feed = _straight_feed(pos, end, rot, r1, tiny, feed_lin, feed_ang)
                    length = math.dist(pos, end)
                    if r1 != rot and length > 0:  # scaled by travel / length of rounded ends
                        seg.feed_tol = abs(seg.feed) * 4 * tol / length
                segs = [seg]
            segs[0].start_tol = end_tol
            for prev, seg in zip(segs, segs[1:]):
                seg.start_tol = prev.tol
            out.segments.extend(segs)
            pos, rot, end_tol = segs[-1].end, segs[-1].rot1, tol
        elif name == "DWELL":
            out.segments.append(
                Seg(DWELL, pos, pos, dwell_s=_nums(args)[0], rot0=rot, rot1=rot, plane=plane)
            )
        elif name in _UNSUPPORTED:
            out.unsupported = out.unsupported or name
    out.error = "; ".join(errors)
    return out


def _straight_feed(p0, p1, r0, r1, tiny, feed_lin, feed_ang) -> float:
    lin = math.dist(p0, p1)
    rot = math.dist(r0, r1)
    if rot == 0:
        return feed_lin
    if any(abs(a - b) > tiny for a, b in zip(p0, p1)):
        return feed_lin * math.hypot(lin, rot) / lin
    return feed_ang


def _arc(n, plane, unit, g5x, g92, pos, rot, feed_lin, tol, start_tol) -> list[Seg]:
    ia, ib, ic = _ARC_AXES[plane]
    end = [0.0, 0.0, 0.0]
    end[ia], end[ib], end[ic] = n[0] * unit, n[1] * unit, n[5] * unit
    end = [end[i] + g5x[i] + g92[i] for i in range(3)]
    ca, cb = n[2] * unit + g5x[ia] + g92[ia], n[3] * unit + g5x[ib] + g92[ib]
    turn = int(n[4])
    r1 = tuple(n[6 + i] + g5x[3 + i] + g92[3 + i] for i in range(3))
    kind = ARC_CCW if turn > 0 else ARC_CW
    # the angle swept: the arc from start to end in its direction, plus the extra full turns
    t0 = math.atan2(pos[ib] - cb, pos[ia] - ca)
    t1 = math.atan2(end[ib] - cb, end[ia] - ca)
    sweep = (t1 - t0) % (2 * math.pi) if turn > 0 else (t0 - t1) % (2 * math.pi)
    if math.hypot(end[ia] - pos[ia], end[ib] - pos[ib]) <= 1e-6:
        sweep = 2 * math.pi
    total = sweep + 2 * math.pi * (abs(turn) - 1)
    radius = math.hypot(pos[ia] - ca, pos[ib] - cb)
    arc_len = math.hypot(radius * total, end[ic] - pos[ic])
    travel = math.hypot(arc_len, math.dist(rot, r1))
    feed = feed_lin * travel / arc_len if arc_len > 0 else feed_lin
    cuts = [2 * math.pi * k / total for k in range(1, abs(turn))] + [1.0]
    segs = []
    f0, a = 0.0, tuple(pos)
    for f1 in cuts:
        b = list(pos) if f1 != 1.0 else list(end)
        if f1 != 1.0:
            b[ic] = pos[ic] + f1 * (end[ic] - pos[ic])
        c = [0.0, 0.0, 0.0]
        c[ia], c[ib], c[ic] = ca, cb, a[ic]
        ra = tuple(x + f0 * (y - x) for x, y in zip(rot, r1))
        rb = tuple(x + f1 * (y - x) for x, y in zip(rot, r1))
        t = tol if f1 == 1.0 else max(tol, start_tol)  # a full turn ends where it starts
        segs.append(Seg(kind, a, tuple(b), tuple(c), feed, rot0=ra, rot1=rb, plane=plane, tol=t))
        f0, a = f1, tuple(b)
    return segs


def motion_segments(motion) -> list[Seg]:
    """cutlab's :class:`~planning.nc.Motion` as :class:`Seg` rows."""
    rows = []
    for i in range(len(motion)):
        rows.append(
            Seg(
                int(motion.kind[i]),
                tuple(float(x) for x in motion.start[i]),
                tuple(float(x) for x in motion.end[i]),
                tuple(float(x) for x in motion.center[i]),
                float(motion.feed_mm_min[i]),
                float(motion.dwell_s[i]),
                tuple(float(x) for x in motion.rotary_start_deg[i]),
                tuple(float(x) for x in motion.rotary_end_deg[i]),
                int(motion.plane[i]),
                int(motion.line[i]),
            )
        )
    return rows


def _moves(segs: list[Seg]) -> list[Seg]:
    """Without the straight moves that go nowhere (within the print rounding: rs274's inch
    output makes a move to where the tool is a hair long)."""
    return [
        s
        for s in segs
        if not (
            s.kind in (RAPID, LINE)
            and _close(s.start, s.end, s.tol + s.start_tol)
            and _close(s.rot0, s.rot1, 1e-4)
        )
    ]


def _close(a, b, tol: float) -> bool:
    return all(abs(x - y) <= tol or (x != x and y != y) for x, y in zip(a, b))


def _fmt(p) -> str:
    if isinstance(p, str):
        return p
    if isinstance(p, float):
        return f"{p:.6g}"
    return "(" + ", ".join(f"{x:.5f}" for x in p) + ")"


def _difference(s: Seg, t: Seg, before: float):
    """The first field where two segments differ, as ``(name, ours, theirs)``, or None
    (``before``: the position tolerance of the segment before, where this one starts)."""
    tol = max(s.tol, t.tol)
    if s.kind != t.kind:
        return "kind", KIND_NAMES[s.kind], KIND_NAMES[t.kind]
    if s.kind == DWELL:
        if abs(s.dwell_s - t.dwell_s) > DWELL_TOL_S:
            return "dwell_s", s.dwell_s, t.dwell_s
        return None
    if not _close(s.start, t.start, max(tol, before)):
        return "start", s.start, t.start
    if not _close(s.end, t.end, tol):
        return "end", s.end, t.end
    if not _close(s.rot0, t.rot0, 1e-4) or not _close(s.rot1, t.rot1, 1e-4):
        return "rotary", s.rot0 + s.rot1, t.rot0 + t.rot1
    if s.kind in (ARC_CW, ARC_CCW):
        if s.plane != t.plane:
            return "plane", float(s.plane), float(t.plane)
        if not _close(s.center, t.center, max(tol, before)):  # its normal coordinate: start's
            return "centre", s.center, t.center
    if s.kind != RAPID:
        ftol = FEED_RTOL * abs(t.feed) + 1e-4 * INCH_MM + t.feed_tol
        if not abs(s.feed - t.feed) <= ftol:
            return "feed mm/min", s.feed, t.feed
    return None


def compare(ours: list[Seg], theirs: list[Seg], file: str) -> Outcome:
    """The first difference between two segment lists (after dropping moves to nowhere)."""
    a, b = _moves(ours), _moves(theirs)
    for i, (s, t) in enumerate(zip(a, b)):
        diff = _difference(s, t, t.start_tol)
        if diff is not None:
            name, x, y = diff
            return Outcome(file, False, i, s.line, f"segment {i} {name}", _fmt(x), _fmt(y))
    if len(a) != len(b):
        i = min(len(a), len(b))
        line = a[i].line if i < len(a) else 0
        more = "ours" if len(a) > len(b) else "rs274"
        return Outcome(file, False, i, line, f"segment count ({more} has more)", str(len(a)),
                       str(len(b)))  # fmt: skip
    return Outcome(file, True, len(a))


# What a program may use for the comparison to mean something: features cutlab's interpreter
# does not have (it refuses them) or whose motion it does not model.
_SCOPE = [
    (
        re.compile(r"^\s*/?\s*(n\s*\d+\s*)?o\s*(<|\d+\s*[a-z])", re.I | re.M),
        "O-word subroutines / control flow",
    ),
    (re.compile(r"#"), "parameters (#)"),
    (re.compile(r"\["), "expressions ([ ])"),
    (re.compile(r"[@^]"), "polar coordinates (@ ^)"),
    (re.compile(r"\bg\s*0*4[12](\.\d)?(?!\d)", re.I), "cutter compensation G41/G42 (not applied)"),
    (
        re.compile(r"\bg\s*0*(7[0-6]|33|38|5\.[0-3]|5(?![0-9.]))(?![0-9])", re.I),
        "lathe / threading / spline cycles (G7x, G33, G5), probing (G38: where a probe stops "
        "depends on the part; rs274's simulated one stops 0.254 mm short of the target)",
    ),
    (
        re.compile(r"\bm\s*0*(7[0-3]|66|6[78]|1\d\d)(?!\d)", re.I),
        "M70-M73 modal state, M66-M68 I/O, M100-M199 user codes",
    ),
    (re.compile(r"\b[uvw]\s*[-+.\d]", re.I), "U V W axes"),
]


def out_of_scope(path: Path) -> str:
    """Why a program is outside what the comparison covers ("" if it is inside)."""
    text = Path(path).read_text(errors="replace")
    code = re.sub(r"\([^)]*\)|;.*", " ", text)
    for rx, why in _SCOPE:
        if rx.search(code):
            return why
    return ""


def compare_file(path: Path, scoped: bool = True, **options) -> Outcome:
    """Run both interpreters on ``path`` and compare (``options`` go to cutlab's Interpreter);
    ``scoped=False`` for programs written for the comparison (in scope by construction)."""
    from planning.nc import Interpreter, NCError
    from planning.nc.run import file_lines

    name = str(path)
    why = out_of_scope(path) if scoped else ""
    if why:
        return Outcome(name, False, skipped=f"uses {why}")
    canon = parse_canon(run_rs274(path))
    if canon.unsupported:
        return Outcome(name, False, skipped=f"rs274 makes {canon.unsupported}, not modelled")
    if not canon.segments:
        reason = f"rs274 refuses it: {canon.error}" if canon.error else "no motion"
        return Outcome(name, False, skipped=reason)
    opts = {"dialect": "linuxcnc", "reference_mm": (0, 0, 0), "second_reference_mm": (0, 0, 0)}
    opts.update(options)
    it = Interpreter(file=name, **opts)
    try:
        motion = it.run(file_lines(path))
        ours_error = ""
    except NCError as exc:
        motion, ours_error = None, str(exc)
    if motion is None:
        # compare what both did before the error: ours stops at the failing block
        it2 = Interpreter(file=name, **opts)
        lines = list(file_lines(path))
        motion = it2.run(lines[: _error_line(ours_error, name) - 1])
    result = compare(motion_segments(motion), canon.segments, name)
    if ours_error or canon.error:
        if bool(ours_error) != bool(canon.error):
            return Outcome(name, False, len(canon.segments), 0, "error",
                           ours_error or "none", canon.error or "none")  # fmt: skip
    return result


def _error_line(message: str, name: str) -> int:
    m = re.match(re.escape(name) + r":(\d+):", message)
    return int(m.group(1)) if m else 1


def compare_folder(folder: Path, pattern: str = "*.ngc", **options) -> list[Outcome]:
    return [compare_file(p, **options) for p in sorted(Path(folder).rglob(pattern))]


def random_program(seed: int, blocks: int = 40) -> str:
    """A random LinuxCNC program (seeded) mixing what the comparison covers: rapids and feeds
    with rotary axes, I/J/K and R arcs in the three planes (helical, P turns), G20/G21 with F in
    the same block, G93/G94, G10 L2/L20, G54..G59.3, the G92 family, G52, canned cycles in the
    three planes with G90/G91, G98/G99 and L, G28/G30 and G28.1/G30.1, G53, path modes, dwells
    with moves."""
    rnd = random.Random(seed)
    out = ["G21 G90 G17 G94 F300"]
    unit = 1.0  # program units per mm
    g93 = False

    def num(span: float = 50.0) -> str:
        return f"{rnd.uniform(-span, span) * unit:.4f}"

    def maybe(p: float, text: str) -> str:
        return text if rnd.random() < p else ""

    for _ in range(blocks):
        k = rnd.random()
        f93 = f" F{rnd.choice([1, 2.5, 4])}" if g93 else ""
        if k < 0.1:
            out.append(f"G0 X{num()} Y{num()} Z{num()}" + maybe(0.3, f" A{num(90)}"))
        elif k < 0.25:
            feed = f93 or maybe(0.3, f" F{rnd.choice([100, 250, 6])}")
            out.append(f"G1 X{num()} Y{num()}" + maybe(0.3, f" B{rnd.uniform(-90, 90):.3f}") + feed)
        elif k < 0.3:
            out.append(f"G1 C{rnd.uniform(-180, 180):.3f}" + f93)
        elif k < 0.45:  # an arc, incremental, in a random plane
            plane = rnd.choice([17, 18, 19])
            a, b, i, j, n = {17: "XYIJZ", 18: "ZXKIY", 19: "YZJKX"}[plane]
            rad = rnd.uniform(1, 20) * unit
            th0, th1 = rnd.uniform(0, 2 * math.pi), rnd.uniform(0, 2 * math.pi)
            ci, cj = -rad * math.cos(th0), -rad * math.sin(th0)
            ea, eb = ci + rad * math.cos(th1), cj + rad * math.sin(th1)
            extra = maybe(0.3, f" {n}{rnd.uniform(-5, 5) * unit:.4f}")
            extra += maybe(0.2, f" P{rnd.randint(1, 3)}") + f93
            if rnd.random() < 0.3:
                centre = f"R{rad * rnd.choice([1, -1]):.4f}"
            else:
                centre = f"{i}{ci:.4f} {j}{cj:.4f}"
            out += [
                f"G{plane} G91",
                f"G{rnd.choice([2, 3])} {a}{ea:.4f} {b}{eb:.4f} {centre}{extra}",
            ]
            out.append("G90 G17")
        elif k < 0.52:
            units = rnd.choice(["G20", "G21"])
            unit = 1 / 25.4 if units == "G20" else 1.0
            out.append(units + ("" if g93 else maybe(0.5, f" F{rnd.choice([5, 60])}")))
        elif k < 0.56:
            g93 = rnd.random() < 0.5
            out.append("G93" if g93 else f"G94 F{rnd.choice([100, 20])}")
        elif k < 0.62:
            out.append(f"G10 L2 P{rnd.randint(0, 9)} X{num()} Y{num()} Z{num()}")
        elif k < 0.66:
            out.append(rnd.choice(["G54", "G55", "G56", "G59.1", "G59.3"]))
        elif k < 0.7:
            out.append(rnd.choice([f"G92 X{num()} Y{num()}", "G92.1", "G92.2", "G92.3",
                                   f"G52 Z{num()}"]))  # fmt: skip
        elif k < 0.8 and not g93:  # a canned cycle in a random plane
            plane = rnd.choice([17, 17, 18, 19])
            a, b, c = {17: "XYZ", 18: "ZXY", 19: "YZX"}[plane]
            mode = rnd.choice(["G90", "G91"])
            bottom, r = rnd.uniform(-20, 0) * unit, rnd.uniform(0, 10) * unit
            if mode == "G91":
                r = rnd.uniform(-10, 5) * unit
            cycle = rnd.choice(
                ["G81", f"G82 P{rnd.uniform(0, 1):.3f}", f"G83 Q{rnd.uniform(1, 5) * unit:.4f}"]
            )
            head = f"G{plane} {mode} {rnd.choice(['G98', 'G99'])} {cycle}"
            out.append(f"{head} {a}{num()} {b}{num()} {c}{bottom:.4f} R{r:.4f}")
            out[-1] += maybe(0.3, f" L{rnd.randint(1, 3)}")
            if rnd.random() < 0.5:
                out.append(f"{rnd.choice(['G98', 'G99', ''])} {a}{num(10)} {b}{num(10)}")
            out.append("G80 G90 G17")
        elif k < 0.85:
            out.append(rnd.choice(["G28", "G30", f"G28 Z{num()}", "G28.1", "G30.1",
                                   "G91 G28 Z0\nG90", f"G53 G0 X{num()}"]))  # fmt: skip
        elif k < 0.9:
            out.append(f"G10 L20 P{rnd.randint(0, 9)} X{num()}")
        elif k < 0.95:
            out.append(rnd.choice(["G61", "G61.1", f"G64 P{rnd.uniform(0, 0.1):.3f}", "G64"]))
        else:
            out.append(f"G4 P{rnd.uniform(0, 2):.3f}" + maybe(0.5, f" G0 X{num()}"))
    out.append("M2")
    return "\n".join(out) + "\n"


__all__ = [
    "INSTALL_HINT",
    "RS274",
    "Canon",
    "Outcome",
    "RS274CutShort",
    "Seg",
    "available",
    "compare",
    "compare_file",
    "compare_folder",
    "out_of_scope",
    "motion_segments",
    "parse_canon",
    "random_program",
    "rs274_ended",
    "run_rs274",
]
