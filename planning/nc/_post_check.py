"""The check of :func:`planning.nc.output.for_dialect` (private): the written program, read back
in its dialect, must move like the source segment by segment (end points within
:data:`MOTION_TOL_MM`, same feeds, dwells, spindle), else nothing is written.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from planning.nc import dialects
from planning.nc.errors import NCError
from planning.nc.interpreter import Interpreter
from planning.nc.motion import Motion
from planning.nc.program import Program
from planning.nc.run import interpret

if TYPE_CHECKING:
    from analysis.config import MachineConfig
    from planning.nc.errors import NCWarning

MOTION_TOL_MM = 1e-6  # the written program moves like the source within this


def _reader(
    dialect: str, machine: MachineConfig | None, program: Program, cutter_comp: str = "warn"
) -> Motion:
    return interpret(program, machine, strict=True, dialect=dialect, file=program.file,
                     cutter_comp=cutter_comp)  # fmt: skip


def _verify(
    source_prog: Program, out: Program, dialect: str, source: str, machine: MachineConfig | None,
    *, keeps_tools: bool,
) -> None:
    """The written program must move like the source (internal check)."""
    d = dialects.get(dialect)
    before = _reader(source, machine, source_prog, "warn" if d.cutter_comp else "refuse")
    if d.post.full_words or not keeps_tools:
        after = _reader(dialect, machine, out)
    else:  # M6 kept for a tool changer: GRBL 1.1 itself would refuse it
        it = Interpreter(machine, strict=False, file=out.file, dialect=dialect)
        after = it.run(out.lines)
        bad = [w for w in it.warnings if not _is_m6(w.word)]
        known = {w.reason for w in _warnings(source_prog, machine, source)}
        bad = [w for w in bad if w.reason not in known]
        if bad:
            raise NCError(f"{d.title} output: {bad[0]}", file=out.file)
    if not keeps_tools:
        before = replace(before, tool=after.tool) if len(before) == len(after) else before
    k = _first_difference(before, after)
    if k is not None:
        line = int(before.line[k]) if k < len(before) else 0
        raise NCError(
            f"the {dialect} program would not move like the source from segment {k} (internal "
            "check failed); nothing written", file=source_prog.file, line=line,
        )  # fmt: skip


def _is_m6(word: str) -> bool:
    w = word.strip().upper()
    try:
        return w[:1] == "M" and float(w[1:]) == 6.0
    except ValueError:
        return False


def _warnings(program: Program, machine: MachineConfig | None, dialect: str) -> list[NCWarning]:
    it = Interpreter(machine, strict=True, file=program.file, dialect=dialect)
    it.skip(program.lines)
    return it.warnings


def _first_difference(a: Motion, b: Motion) -> int | None:
    """Index of the first segment that moves otherwise (None: the same motion)."""
    n = min(len(a), len(b))
    bad = []
    for name in ("kind", "plane", "tool", "coolant"):
        bad.append(getattr(a, name)[:n] != getattr(b, name)[:n])
    for name in ("start", "end", "center", "rotary_start_deg", "rotary_end_deg"):
        x, y = getattr(a, name)[:n], getattr(b, name)[:n]
        bad.append(~(_close(x, y, MOTION_TOL_MM)).all(axis=1))
    bad.append(~_close(a.dwell_s[:n], b.dwell_s[:n], MOTION_TOL_MM))
    bad.append(~_close(a.spindle_rpm[:n], b.spindle_rpm[:n], 1e-9))
    fa, fb = a.feed_mm_min[:n], b.feed_mm_min[:n]
    bad.append(~_close(fa, fb, 1e-9 * max(1.0, _finite_max(fa))))
    mask = np.logical_or.reduce(bad) if bad else np.zeros(n, bool)
    hits = np.nonzero(mask)[0]
    if len(hits):
        return int(hits[0])
    return None if len(a) == len(b) else n


def _close(x: npt.ArrayLike, y: npt.ArrayLike, tol: float) -> npt.NDArray[np.bool_]:
    return np.isclose(x, y, rtol=0.0, atol=tol, equal_nan=True)


def _finite_max(x: npt.NDArray[np.float64]) -> float:
    f = x[np.isfinite(x)]
    return float(np.abs(f).max()) if len(f) else 0.0
