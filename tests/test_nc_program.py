"""Programs as text: exact round trips, edits that touch only their words, the writer
(motion -> NC -> motion) and feed splitting that keeps the path (hypothesis)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from planning.nc import (
    ARC_CCW,
    ARC_CW,
    LINE,
    RAPID,
    MotionBuilder,
    NCError,
    Program,
    arc_sweep_rad,
    interpret,
    motion_to_program,
    tokenize,
)
from planning.nc.edit import set_feed, split_moves

SAMPLE = str(Path(__file__).resolve().parents[1] / "data" / "programs" / "demo-part.nc")
HYP = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


# ------------------------------------------------------------------ random programs
@st.composite
def programs(draw):
    """Text of a random program: lines and arcs (I/J/K or R), G90/G91, G20/G21, and layout
    variety (case, spacing, comments, N numbers, trailing-dot numbers)."""
    inch = draw(st.booleans())
    absolute = draw(st.booleans())
    u = 25.4 if inch else 1.0
    dec = 5 if inch else 4
    spaced = draw(st.booleans())
    lower = draw(st.booleans())
    numbered = draw(st.booleans())
    sep = " " if spaced else ""

    def num(v):
        s = f"{v:.{dec}f}".rstrip("0")
        return s if s != "-0." else "0."

    out = ["%", "(RANDOM)", ("G20" if inch else "G21") + sep + "G90" + sep + "G17"]
    pos = np.array([0.0, 0.0, 0.0])
    out.append("G0" + sep + "X0" + sep + "Y0" + sep + "Z0")
    if not absolute:
        out.append("G91")
    n = draw(st.integers(1, 8))
    for i in range(n):
        words = []
        if draw(st.booleans()) or i == 0:
            words.append("F" + num(draw(st.floats(50, 2000)) / u))
        kind = draw(st.sampled_from(["line", "arc"]))
        if kind == "line":
            target = pos + np.array(
                [draw(st.floats(-50, 50)), draw(st.floats(-50, 50)), draw(st.floats(-5, 5))]
            )
            txt = [num((target[a] if absolute else target[a] - pos[a]) / u) for a in range(3)]
            new = np.array([float(t) * u for t in txt]) + (0 if absolute else pos)
            words = ["G1", *[L + t for L, t in zip("XYZ", txt)], *words]
        else:
            r = draw(st.floats(1, 40))
            phi0 = draw(st.floats(0, 2 * math.pi))
            sweep = draw(st.floats(0.2, 2 * math.pi - 0.2))
            cw = draw(st.booleans())
            use_r = draw(st.booleans()) and abs(sweep - math.pi) > 0.2
            c = pos[:2] - r * np.array([math.cos(phi0), math.sin(phi0)])
            th = phi0 - sweep if cw else phi0 + sweep
            end = np.array([c[0] + r * math.cos(th), c[1] + r * math.sin(th), pos[2]])
            end[2] += draw(st.floats(-3, 3))
            txt = [num((end[a] if absolute else end[a] - pos[a]) / u) for a in range(3)]
            new = np.array([float(t) * u for t in txt]) + (0 if absolute else pos)
            centre = (
                [f"R{num((r if sweep < math.pi else -r) / u)}"]
                if use_r
                else ["I" + num((c[0] - pos[0]) / u), "J" + num((c[1] - pos[1]) / u)]
            )
            words = ["G2" if cw else "G3", *[L + t for L, t in zip("XYZ", txt)], *centre, *words]
        pos = new
        text = sep.join(words)
        if numbered:
            text = f"N{10 * (i + 1)}{sep}{text}"
        if draw(st.booleans()):
            text += " (C" + str(i) + ")"
        out.append(text.lower() if lower else text)
    out += ["M30", "%"]
    return "\n".join(out) + "\n"


def _arc_tol(text: str) -> float:
    return 0.01  # R/IJK rounded to 4-5 decimals: keep the tolerance out of the way


# ------------------------------------------------------------------ text round trip
@HYP
@given(programs())
def test_parse_write_parse_is_identical(text):
    prog = Program.parse(text)
    assert prog.text() == text
    again = Program.parse(prog.text())
    assert interpret(again, arc_tolerance_mm=0.01).equals(interpret(text, arc_tolerance_mm=0.01))


def test_sample_round_trips_byte_for_byte(tmp_path):
    prog = Program.read(SAMPLE)
    out = tmp_path / "copy.nc"
    prog.write(out)
    assert out.read_bytes() == open(SAMPLE, "rb").read()
    crlf = prog.text().replace("\n", "\r\n")
    assert Program.parse(crlf).text() == crlf


# ------------------------------------------------------------------ edits
@HYP
@given(programs(), st.data())
def test_set_word_changes_only_that_word(text, data):
    prog = Program.parse(text)
    motion_blocks = [i for i in range(len(prog)) if prog.get_word(i, "X") is not None]
    i = data.draw(st.sampled_from(motion_blocks))
    before = list(prog.lines)
    had_f = prog.get_word(i, "F")
    prog.set_word(i, "F", 123.25)
    assert prog.lines[:i] == before[:i] and prog.lines[i + 1 :] == before[i + 1 :]
    old, new = tokenize(before[i]), tokenize(prog.lines[i])
    if had_f:
        keep = [t.text for t in old if not (t.kind == "word" and t.letter == "F")]
        assert [t.text for t in new if not (t.kind == "word" and t.letter == "F")] == keep
        assert len(new) == len(old)
    else:  # added after the last word, with the block's own separator
        sep = " " if " " in before[i].split("(")[0].strip() else ""
        assert prog.lines[i].replace(sep + "F123.25", "", 1) == before[i]
    assert prog.get_word(i, "F") == "123.25"


def test_edit_api_on_sample():
    prog = Program.read(SAMPLE)
    b = next(i for i, s in enumerate(prog.lines) if s.startswith("N80 "))
    assert prog.lines[b] == "N80 X40. F800."
    prog.set_word(b, "F", 650)
    assert prog.lines[b] == "N80 X40. F650."  # trailing-dot style is that of the program
    prog.set_word(b, "y", 3.5)
    assert prog.lines[b] == "N80 X40. F650. Y3.5"
    prog.remove_word(b, "Y")
    prog.replace_word(b, "X40", "X41.")
    assert prog.lines[b] == "N80 X41. F650."
    c = next(i for i, s in enumerate(prog.lines) if s.startswith("N20 "))
    new_index = prog.replace_blocks({c: [{"T": 5, "M": 6}, "(SECOND TOOL)"]})
    assert prog.lines[c : c + 2] == ["N20 T5 M6 (PHI10 FLAT END MILL)", "(SECOND TOOL)"]
    assert new_index[c + 1] == c + 2
    with pytest.raises(ValueError, match="replace_word"):
        prog.set_word(b, "G", 1)
    with pytest.raises(NCError, match="out of range"):
        prog.set_word(len(prog), "F", 1)
    with pytest.raises(NCError, match="tape mark"):
        prog.set_word(0, "F", 1)
    prog.set_word(1, "S", 100)  # a comment-only block takes the word before its comment
    assert prog.lines[1].startswith("O1001 S100 (CUTLAB DEMO PART")


def test_spaceless_block_gets_spaceless_words():
    prog = Program.parse("g1x10y5f300\n")
    prog.set_word(0, "Z", -1)
    prog.set_word(0, "F", 250)
    assert prog.lines == ["g1x10y5f250Z-1"]


def test_set_feed_inch():
    prog = Program.parse("G20 G1 X1 F10\n")
    set_feed(prog, 0, 127.0, inch=True)
    assert prog.get_word(0, "F") == "5"


# ------------------------------------------------------------------ writer
@st.composite
def motions(draw):
    b = MotionBuilder()
    p = np.zeros(3)
    tool, rpm = 1, 3000.0
    for _ in range(draw(st.integers(1, 12))):
        kind = draw(st.sampled_from([RAPID, LINE, ARC_CW, ARC_CCW]))
        plane = draw(st.sampled_from([17, 18, 19]))
        if draw(st.integers(0, 5)) == 0:
            tool = draw(st.integers(1, 20))
        if draw(st.integers(0, 5)) == 0:
            rpm = draw(st.sampled_from([0.0, 1000.0, -2500.0]))
        feed = draw(st.floats(10, 5000)) if kind != RAPID else np.nan
        if kind in (RAPID, LINE):
            q = p + np.array([draw(st.floats(-30, 30)) for _ in range(3)])
            b.add(kind, p, q, plane=plane, feed_mm_min=feed, tool=tool, spindle_rpm=rpm)
        else:
            from planning.nc.arcs import PLANE_AXES

            ia, ib, ic = PLANE_AXES[plane]
            r = draw(st.floats(1, 30))
            phi = draw(st.floats(0, 2 * math.pi))
            sweep = draw(st.floats(0.1, 2 * math.pi))
            c = p.copy()
            c[ia] -= r * math.cos(phi)
            c[ib] -= r * math.sin(phi)
            th = phi + (sweep if kind == ARC_CCW else -sweep)
            q = c.copy()
            q[ia] += r * math.cos(th)
            q[ib] += r * math.sin(th)
            q[ic] = p[ic] + draw(st.floats(-5, 5))
            c[ic] = p[ic]
            b.add(kind, p, q, c, plane=plane, feed_mm_min=feed, tool=tool, spindle_rpm=rpm)
        p = q
    return b.build()


@HYP
@given(motions())
def test_motion_to_program_round_trip(m):
    prog = motion_to_program(m)
    back = interpret(Program.parse(prog.text()), arc_tolerance_mm=0.001)
    assert back.same_path(m, atol_mm=2e-4, feed_rtol=1e-6)
    # and the written text itself round trips exactly
    assert interpret(prog, arc_tolerance_mm=0.001).equals(back)


# ------------------------------------------------------------------ feed splitting
@HYP
@given(programs(), st.data())
def test_split_moves_keeps_the_path(text, data):
    prog = Program.parse(text)
    m = interpret(prog, arc_tolerance_mm=0.01)
    feeds = [int(i) for i in np.nonzero(m.is_feed)[0]]
    chosen = data.draw(st.lists(st.sampled_from(feeds), unique=True, max_size=len(feeds)))
    plan = {}
    for s in chosen:
        k = data.draw(st.integers(1, 4))
        ts = sorted(set(data.draw(st.lists(st.floats(0.05, 0.95), min_size=k - 1, max_size=k - 1))))
        ts = [t for t, u in zip(ts, [0.0, *ts]) if t - u > 0.01] + [1.0]
        plan[s] = [(t, float(data.draw(st.integers(20, 3000)))) for t in ts]
    new = split_moves(prog, plan, arc_tolerance_mm=0.01)
    m2 = interpret(new, arc_tolerance_mm=0.01)
    assert len(m2) == len(m) + sum(len(p) - 1 for p in plan.values())
    j = 0
    for s in range(len(m)):
        pieces = plan.get(s, [(1.0, m.feed_mm_min[s])])
        part = m2[j : j + len(pieces)]
        j += len(pieces)
        assert np.all(part.kind == m.kind[s])
        np.testing.assert_allclose(part.start[0], m.start[s], atol=1e-9)
        np.testing.assert_allclose(part.end[-1], m.end[s], atol=1e-9)
        np.testing.assert_allclose(part.start[1:], part.end[:-1], atol=1e-9)
        np.testing.assert_allclose(
            part.feed_mm_min, [f for _, f in pieces], rtol=1e-4, equal_nan=True
        )
        if m.is_arc[s]:
            # same centre in the plane (G17 here); its Z is each piece's start Z by definition
            np.testing.assert_allclose(
                part.center[:, :2], np.repeat(m.center[s : s + 1, :2], len(part), 0), atol=3e-4
            )
            # every piece end lies on the original arc at the planned fraction of its sweep
            c, p0 = m.center[s, :2], m.start[s, :2]
            r = np.linalg.norm(p0 - c)
            ends = part.end[:-1, :2] - c  # the last end is the source's own (checked above)
            np.testing.assert_allclose(np.linalg.norm(ends, axis=1), r, atol=3e-4)
            sgn = 1.0 if m.kind[s] == ARC_CCW else -1.0
            a0 = math.atan2(p0[1] - c[1], p0[0] - c[0])
            turned = np.mod(sgn * (np.arctan2(ends[:, 1], ends[:, 0]) - a0), 2 * math.pi)
            want = np.array([t for t, _ in pieces[:-1]]) * arc_sweep_rad(m[s : s + 1])[0]
            err = np.abs(np.mod(turned - want + math.pi, 2 * math.pi) - math.pi)
            assert err.max(initial=0.0) < 3e-4 / r + 1e-9
        else:
            d = m.end[s] - m.start[s]
            for t, q in zip([t for t, _ in pieces], part.end):
                np.testing.assert_allclose(q, m.start[s] + t * d, atol=2e-4)
    assert j == len(m2)
    # untouched blocks are still there, verbatim and in order
    edited = {int(m.block[s]) for s in plan}
    keep = [ln for i, ln in enumerate(prog.lines) if i not in edited]
    it = iter(new.lines)
    assert all(any(ln == x for x in it) for ln in keep)


def test_split_refuses_canned_cycles_and_bad_plans():
    prog = Program.parse("G0 Z5\nG1 F100\nG81 X1 Y1 Z-2 R1\nG80\nG1 X10\n")
    with pytest.raises(NCError, match="canned cycle"):
        split_moves(prog, {2: [(1.0, 50.0)]})
    seg = len(interpret(prog)) - 1
    with pytest.raises(NCError, match="end at t = 1.0"):
        split_moves(prog, {seg: [(0.5, 50.0)]})
    with pytest.raises(NCError, match="must increase"):
        split_moves(prog, {seg: [(0.5, 50.0), (0.4, 60.0), (1.0, 70.0)]})
    with pytest.raises(NCError, match="not a feed move"):
        split_moves(prog, {0: [(1.0, 50.0)]})


def test_split_points_are_written_in_the_g92_frame() -> None:
    # G92 X100 at machine X0: the move X100 -> X140 (machine 0 -> 40) split at half is X120 in the
    # program's frame (the written word), not the machine's X20.
    from planning.nc.edit import split_moves

    text = "G21 G90 G17\nG0 X0 Y0 Z5\nG92 X100 Y0 Z5\nG1 Z-1 F100\nG1 X140 F200\nM30\n"
    prog = Program.parse(text)
    new = split_moves(prog, {2: [(0.5, 400.0), (1.0, 650.0)]})
    assert new.text().splitlines()[4:6] == ["G1 X120 F400", "X140 F650"]
