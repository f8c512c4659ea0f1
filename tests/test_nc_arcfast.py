"""The vectorised path for runs of plain G0..G3 blocks takes arcs too (``Interpreter(fast=True)``,
the default): bit for bit the Motion, state, warnings and errors of the block-by-block path, in
G17/G18/G19, by I J K and by R, G90/G91, G90.1/G91.1, inch, helical, with F changes, and with
the arcs the per-block path refuses (radius mismatch, R too small, words of the wrong plane)."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import pytest
from _fastpath import check_fast_is_slow
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from planning.nc.arcs import PLANE_AXES
from planning.nc.errors import NCError
from planning.nc.interpreter import Interpreter
from planning.nc.run import interpret


def _fmt(v: float, digits: int) -> str:
    text = f"{v:.{digits}f}"
    return "0" if float(text) == 0.0 and text.startswith("-") and digits % 2 else text


@st.composite
def _arc_programs(draw) -> list[str]:
    plane = draw(st.sampled_from([17, 18, 19]))
    inch = draw(st.booleans())
    absolute = draw(st.booleans())
    abs_centre = draw(st.integers(0, 3)) == 0
    head = [
        f"G{20 if inch else 21} G{plane} G{90 if absolute else 91} G94",
        "G90.1" if abs_centre else "G91.1",
    ]
    if draw(st.booleans()):
        head.append("G92 X1.5 Y-2 Z0.25")
    head.append("G1 F" + draw(st.sampled_from(["500", "12.5", "1200"])))
    ia, ib, ic = PLANE_AXES[plane]
    pos = [0.0, 0.0, 0.0]  # program coordinates (G92 makes the current point 1.5, -2, 0.25)
    if len(head) == 4:
        pos = [1.5, -2.0, 0.25]
    lines = list(head)
    digits = 5 if inch else draw(st.sampled_from([3, 4]))
    faulty = draw(st.integers(0, 2)) == 0  # some programs have refused blocks
    for _ in range(draw(st.integers(8, 60))):
        kind = draw(st.integers(0, 9))
        words: list[tuple[str, str]] = []
        if draw(st.integers(0, 4)) == 0:
            words.append(("N", str(draw(st.integers(0, 9999)))))
        if kind <= 1:  # a line
            end = list(pos)
            for ax in draw(st.lists(st.integers(0, 2), min_size=1, max_size=3, unique=True)):
                end[ax] = round(pos[ax] + draw(st.floats(-20, 20)), digits)
            g = draw(st.sampled_from(["G0", "G1", "G01", ""]))
            if g:
                words.append(("G", g[1:]))
            for ax in range(3):
                if end[ax] != pos[ax]:
                    d = end[ax] if absolute else end[ax] - pos[ax]
                    words.append(("XYZ"[ax], _fmt(d, digits)))
            if len(words) == (1 if g else 0) + (1 if words and words[0][0] == "N" else 0):
                words.append(("XYZ"[ia], _fmt(pos[ia] if absolute else 0.0, digits)))
        else:
            cw = draw(st.booleans())
            words.append(("G", draw(st.sampled_from(["2", "02"] if cw else ["3", "03"]))))
            r = draw(st.floats(0.05, 40))
            t0 = draw(st.floats(-math.pi, math.pi))
            sweep = draw(st.floats(0.01, 2 * math.pi))
            full = draw(st.integers(0, 12)) == 0
            ca, cb = pos[ia] - r * math.cos(t0), pos[ib] - r * math.sin(t0)
            t1 = t0 + (-sweep if cw else sweep)
            end = list(pos)
            if not full:
                end[ia] = round(ca + r * math.cos(t1), digits)
                end[ib] = round(cb + r * math.sin(t1), digits)
            if draw(st.integers(0, 3)) == 0:  # helix
                end[ic] = round(pos[ic] + draw(st.floats(-5, 5)), digits)
            fault = draw(st.integers(0, 40)) if faulty else 0
            if fault == 1:  # radius mismatch
                end[ia] = round(end[ia] + draw(st.sampled_from([0.003, 0.05, 1.0, -0.3])), digits)
            for ax in range(3):
                if end[ax] != pos[ax] or (ax != ic and draw(st.integers(0, 3)) == 0):
                    d = end[ax] if absolute else end[ax] - pos[ax]
                    words.append(("XYZ"[ax], _fmt(d, digits)))
            if not any(w[0] in "XYZ" for w in words):
                words.append(("XYZ"[ia], _fmt(end[ia] if absolute else 0.0, digits)))
            by_r = not full and draw(st.integers(0, 2)) == 0
            la, lb, ln = "IJK"[ia], "IJK"[ib], "IJK"[ic]
            if by_r:
                big = sweep > math.pi
                rv = -r if big else r
                if fault == 2:  # too small
                    rv *= 0.5
                if fault == 3:
                    rv = 0.0
                words.append(("R", _fmt(rv, digits)))
                if fault == 4:
                    words.append((la, "1"))
            else:
                ci, cj = (ca, cb) if abs_centre else (ca - pos[ia], cb - pos[ib])
                cw_words = [(la, _fmt(ci, digits)), (lb, _fmt(cj, digits))]
                if fault == 5:
                    cw_words = cw_words[:1]  # one centre word (G90.1: an error)
                if fault == 6:
                    cw_words = []  # no centre at all
                words += sorted(cw_words, key=lambda w: "IJK".index(w[0]))
                if fault == 7:
                    words.append((ln, "0.5"))  # out of plane
            pos = [float(x) for x in end]
        if draw(st.integers(0, 5)) == 0:
            bad_f = ["0", "-2"] if faulty else []
            words.append(("F", draw(st.sampled_from(["300", "750.5", "99999", *bad_f]))))
        if faulty and draw(st.integers(0, 40)) == 0 and kind <= 1:
            words.append(("I", "1"))  # I on a line
        if draw(st.integers(0, 10)) == 0:  # a word order the fast regex does not take
            words.reverse()
        sep = draw(st.sampled_from([" ", "", " (c) "]))
        text = sep.join(f"{L}{n}" for L, n in words)
        if draw(st.integers(0, 8)) == 0:
            text = text.lower()
        lines.append(text + draw(st.sampled_from(["\n", "", "\r\n"])))
        if draw(st.integers(0, 25)) == 0:
            lines.append(draw(st.sampled_from(["F800", "M3 S100", "G94", "M8", "T1 M6"])))
    return lines


_SETTINGS = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@pytest.mark.long
@_SETTINGS
@given(_arc_programs(), st.sampled_from(["fanuc", "linuxcnc", "grbl"]), st.booleans())
def test_generated_arc_programs_same_with_and_without_the_fast_path(lines, dialect, strict):
    check_fast_is_slow(lines, dialect=dialect, strict=strict)


@pytest.mark.long
@_SETTINGS
@given(_arc_programs(), st.integers(1, 40))
def test_generated_arc_programs_same_in_chunks(lines, chunk):
    check_fast_is_slow(lines, chunk=chunk)


@pytest.mark.long
@settings(max_examples=100, deadline=None)
@given(_arc_programs(), st.sampled_from([0.0005, 0.01, 0.5]))
def test_arc_tolerance_option(lines, tol):
    check_fast_is_slow(lines, arc_tolerance_mm=tol)
    check_fast_is_slow(lines, arc_tolerance_mm=tol, dialect="linuxcnc")


def _zigzag(n: int) -> list[str]:
    """The bench's mixed arcs (bench/bench_nc_rs274.py, imported by path: bench is no package)."""
    spec = importlib.util.spec_from_file_location(
        "bench_nc_rs274", Path(__file__).parents[1] / "bench" / "bench_nc_rs274.py"
    )
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    return bench.arc_lines(n)


def test_bench_arcs_identical_and_fast_path_taken():
    lines = _zigzag(2000)
    check_fast_is_slow(lines)
    check_fast_is_slow(lines, chunk=333)
    check_fast_is_slow(lines, dialect="linuxcnc")
    calls = []
    it = Interpreter()
    execute = it._execute
    it._execute = lambda *a: (calls.append(a), execute(*a))[1]
    m = it.run(lines)
    assert len(m) == 2002 and len(calls) < 10  # all but the first blocks and M2 vectorised


@pytest.mark.parametrize(
    "bad",
    [
        "G2 X10 Y0 I4 J0",  # radius mismatch
        "G3 X10 Y0 R4",  # R smaller than half the chord
        "G2 X10 Y0 R0",
        "G2 X10 Y0 I5 R5",
        "G2 X10 Y0",
        "G2 X10 Y0 I5 K1",
        "G1 X10 Y0 I5",
        "G2 X0 Y0 R5",  # R with start = end
        "G2 X0 Y0 I0 J0",  # radius 0
    ],
)
@pytest.mark.parametrize("strict", [True, False])
def test_refused_arcs_same_error_in_a_run(bad, strict):
    lines = ["G21 G90 G17 G1 F100\n", *_zigzag(40)[3:-1], "G0 X0 Y0\n", bad + "\n"]
    lines += _zigzag(40)[3:]
    check_fast_is_slow(lines, strict=strict)
    check_fast_is_slow(lines, strict=strict, dialect="linuxcnc")


def test_arc_error_names_the_block():
    lines = ["G1 F100\n", *_zigzag(40)[3:-1], "G0 X0 Y0\n", "G2 X10 Y0 I4 J0\n"]
    with pytest.raises(NCError) as exc:
        interpret(lines, file="a.ngc")
    assert exc.value.line == len(lines) and "radius" in str(exc.value)
