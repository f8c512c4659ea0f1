"""Differential tier: cutlab's interpreter (dialect "linuxcnc") against LinuxCNC's own ``rs274``,
segment by segment (kinds, end points, arc centres, feeds, dwells, rotary axes; see
``tests/_rs274.py`` for how rs274's canonical calls are read and compared).

* the programs in tests/data/nc/rs274 (one per feature: arcs in G17/G18/G19, inch arcs rounded
  to 4 decimals, G91, canned cycles, G10 L2/L20 and G54..G59.3, G92 and G52, G28/G30, tool
  length and G43.1, G38.x probing, path modes, the order of execution of F and G20, dwells, inch
  offsets) must run through rs274 without an error and agree;
* every example program LinuxCNC ships that is inside what cutlab interprets must agree; the
  others are skipped with the reason (O-word subroutines, parameters, expressions, polar
  coordinates, cutter compensation, lathe/threading/probing cycles, M70-M73 and user M codes,
  U V W axes, no motion, or refused by rs274 itself);
* random programs (seeded: ``_rs274.random_program``) mixing all of the above must agree.

An rs274 run that does not reach the end of the program (nor an error of its own) is run again, up
to 3 times, then the test fails saying rs274 was cut short; each run has its own $HOME (rs274 maps
``$HOME/.tool.mmap``, which a second rs274 truncates: SIGBUS after 5 canonical calls).

Skipped when ``/usr/bin/rs274`` is absent (``apt-get install linuxcnc-uspace``); the parsing of
rs274's output is tested on a stored sample in any case.
"""

from __future__ import annotations

import threading
from pathlib import Path

import _rs274
import pytest
from _rs274 import ARC_CW, LINE, compare, compare_file, out_of_scope, parse_canon

HERE = Path(__file__).parent
OWN = sorted((HERE / "data" / "nc" / "rs274").glob("*.ngc"))
NCFILES = Path("/usr/share/linuxcnc/ncfiles")
SAMPLES = Path("/usr/share/doc/linuxcnc/examples/sample-configs")
# shipped examples inside cutlab's scope: these must be compared (not skipped) and agree
IN_SCOPE = [
    NCFILES / "3dtest.ngc",
    NCFILES / "arcspiral.ngc",
    NCFILES / "b-index.ngc",
    NCFILES / "cds.ngc",
    NCFILES / "lathe_pawn.ngc",
    NCFILES / "plasmatest.ngc",
    NCFILES / "skeleton.ngc",
    NCFILES / "tort.ngc",
    SAMPLES / "sim/craftsman/screens/craftsmancnc.ngc",
    SAMPLES / "sim/axis/vismach/puma/puma_seam_weld.ngc",
    SAMPLES / "sim/axis/remap/extend-builtins/nc_files/examples.ngc",
    SAMPLES / "sim/gmoccapy/non_trivial_kinematics/table-rotary-tilting/examples/boat-xyzac.ngc",
    SAMPLES / "sim/gmoccapy/non_trivial_kinematics/table-rotary-tilting/examples/boat-xyzbc.ngc",
    SAMPLES / "sim/gmoccapy/non_trivial_kinematics/table-rotary-tilting/examples/"
    "impeller-7bl-xyzac.ngc",
]

needs_rs274 = pytest.mark.skipif(
    not _rs274.available(), reason=f"LinuxCNC's rs274 not installed ({_rs274.INSTALL_HINT})"
)


def test_own_programs_exist():
    assert len(OWN) >= 12


@needs_rs274
@pytest.mark.parametrize("path", OWN, ids=[p.name for p in OWN])
def test_own_programs_agree_with_rs274(path: Path):
    canon = parse_canon(_rs274.run_rs274(path))
    assert canon.error == "" and canon.segments, canon.error  # the whole program runs in rs274
    out = compare_file(path, scoped=False)  # (probing.ngc: each probe's axis named after it)
    assert out.agree, str(out)


@needs_rs274
@pytest.mark.parametrize("path", IN_SCOPE, ids=[p.name for p in IN_SCOPE])
def test_shipped_examples_in_scope_agree(path: Path):
    if not path.exists():
        pytest.skip(f"{path} is not in this LinuxCNC version")
    out = compare_file(path)
    assert not out.skipped and out.agree, str(out)


@needs_rs274
def test_no_shipped_example_differs():
    files = sorted(NCFILES.rglob("*.ngc"))
    if not files:
        pytest.skip(f"no example programs in {NCFILES}")
    outcomes = [compare_file(p) for p in files]
    differ = [str(o) for o in outcomes if not o.agree and not o.skipped]
    assert differ == []
    assert sum(o.agree for o in outcomes) >= 8  # the comparison is not vacuous


@needs_rs274
@pytest.mark.parametrize("seed", range(30))
def test_random_programs_agree_with_rs274(seed: int, tmp_path: Path):
    path = tmp_path / f"random{seed}.ngc"
    path.write_text(_rs274.random_program(seed))
    out = compare_file(path)
    assert out.agree, str(out) + "\n" + path.read_text()


@needs_rs274
def test_the_comparison_sees_differences():
    # the same programs read as Fanuc (G4 P in ms, F after G20, units of F) do not agree
    for name, field in (
        ("dwell.ngc", "error"),
        ("feed_order.ngc", "feed"),
        ("canned.ngc", "dwell"),
    ):
        out = compare_file(HERE / "data" / "nc" / "rs274" / name, dialect="fanuc")
        assert not out.agree and field in out.field, str(out)


SAMPLE = """executing
    1 N..... USE_LENGTH_UNITS(CANON_UNITS_MM)
    2 N..... SET_G5X_OFFSET(1, 10.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)
    3 N..... SET_FEED_RATE(6.0000)
    4 N..... USE_LENGTH_UNITS(CANON_UNITS_INCHES)
    5 N..... STRAIGHT_FEED(1.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)
    6 N..... SELECT_PLANE(CANON_PLANE_XZ)
    7 N..... ARC_FEED(1.0000, 3.0000, 1.0000, 2.0000, -1, 0.0000, 0.0000, 0.0000, 0.0000)
    8 N..... DWELL(1.5000)
Radius to end of arc differs from radius to start
"""


def test_parse_canon_by_hand():
    canon = parse_canon(SAMPLE)
    assert canon.error == "Radius to end of arc differs from radius to start"
    line, arc, dwell = canon.segments
    # the feed was set in mm (before USE_LENGTH_UNITS(INCHES)); X1 in + the 10 mm offset
    assert line.kind == LINE and line.end == (35.4, 0.0, 0.0) and line.feed == 6.0
    # XZ plane: first = Z, second = X; end Z1 X3 in, centre Z1 X2 in, plus the offset on X
    assert arc.kind == ARC_CW and arc.plane == 18
    assert arc.end == pytest.approx((86.2, 0.0, 25.4)) and arc.center[0] == pytest.approx(60.8)
    assert arc.center[2] == pytest.approx(25.4)
    assert dwell.dwell_s == 1.5 and dwell.end == arc.end


def test_compare_reports_the_first_difference():
    a = parse_canon(SAMPLE).segments
    b = parse_canon(SAMPLE.replace("DWELL(1.5000)", "DWELL(2.0000)")).segments
    assert compare(a, a, "p").agree
    out = compare(a, b, "p")
    assert (
        not out.agree
        and out.field == "segment 2 dwell_s"
        and (out.ours, out.theirs)
        == (
            "1.5",
            "2",
        )
    )


def test_scope_reasons(tmp_path: Path):
    cases = {
        "o100 sub\no100 endsub": "O-word",
        "#1 = 2\nG0 X#1": "parameters",
        "G0 X[1+2]": "expressions",
        "G0 @1 ^30": "polar",
        "G41 D1 G1 X1 F10": "cutter compensation",
        "G38.2 Z-1 F10": "probing",
        "M70": "M70",
        "G0 U1": "U V W",
        "G0 X1 (o100 sub in a comment) ; #1": "",
        "G54 G0 X1\nG53 G0 Z0\nG55 G59.3 G50": "",
    }
    for text, why in cases.items():
        p = tmp_path / "p.ngc"
        p.write_text(text + "\nM2\n")
        assert (why in out_of_scope(p)) if why else out_of_scope(p) == "", text


# what a run killed by another rs274 printed (SIGBUS, status -7): no end of program, no error
CUT_SHORT = """    1 N..... USE_LENGTH_UNITS(CANON_UNITS_MM)
    2 N..... SET_G5X_OFFSET(1, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)
    3 N..... SET_G92_OFFSET(0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)
    4 N..... SET_XY_ROTATION(0.0000)
    5 N..... SET_FEED_REFERENCE(CANON_XYZ)
executing
"""
WHOLE = (
    CUT_SHORT
    + """    6 N..... STRAIGHT_FEED(4.0000, 5.0000, 3.0000, 0.0000, 0.0000, 0.0000)
    7 N..... PROGRAM_END()
    8 N..... ON_RESET()
"""
)


def test_a_cut_short_rs274_run_is_told_from_an_ended_one():
    assert _rs274.rs274_ended(0, WHOLE) == ""
    assert _rs274.rs274_ended(0, WHOLE.replace("PROGRAM_END", "FINISH")) == ""  # closing "%"
    assert _rs274.rs274_ended(1, CUT_SHORT + "Bad character 'w' used\n") == ""  # its own error
    assert _rs274.rs274_ended(-7, CUT_SHORT) == "killed by SIGBUS after 5 canonical calls"
    assert "no end of program" in _rs274.rs274_ended(0, CUT_SHORT)
    assert "no end of program" in _rs274.rs274_ended(1, "")  # status 1 and nothing said
    assert _rs274.rs274_ended(-7, WHOLE).startswith("killed by SIGBUS")


def _flaky_rs274(tmp_path: Path, cut_first: int) -> Path:
    """A stand-in for rs274 killed by SIGBUS (as a shared .tool.mmap did) on its first
    ``cut_first`` runs, then printing a whole program."""
    count, script = tmp_path / "count", tmp_path / "rs274"
    whole = "".join(f"echo '{ln}'\n" for ln in WHOLE.splitlines())
    script.write_text(
        "#!/bin/sh\n"
        f"n=$(cat {count} 2>/dev/null || echo 0); n=$((n + 1)); echo $n > {count}\n"
        f"echo '{CUT_SHORT.splitlines()[0]}'\n"
        f'if [ "$n" -le {cut_first} ]; then kill -BUS $$; fi\n' + whole
    )
    script.chmod(0o755)
    return script


@pytest.mark.faults
def test_a_cut_short_rs274_run_is_retried(tmp_path: Path, caplog):
    prog = tmp_path / "p.ngc"
    prog.write_text("G1 X4 Y5 Z3 F300\nM2\n")
    with caplog.at_level("WARNING", logger="_rs274"):
        text = _rs274.run_rs274(prog, rs274=_flaky_rs274(tmp_path, 2))
    assert text.rstrip().endswith("ON_RESET()") and "PROGRAM_END()" in text
    tries = [r.getMessage() for r in caplog.records if "cut short" in r.getMessage()]
    assert len(tries) == 2 and "try 1: killed by SIGBUS after 1 canonical calls" in tries[0]


@pytest.mark.faults
def test_an_rs274_cut_short_three_times_fails_as_such(tmp_path: Path):
    prog = tmp_path / "p.ngc"
    prog.write_text("G1 X4 Y5 Z3 F300\nM2\n")
    with pytest.raises(_rs274.RS274CutShort, match=r"rs274 was cut short on .*p\.ngc \(try 1: "
                       r"killed by SIGBUS.*try 3: killed by SIGBUS"):  # fmt: skip
        _rs274.run_rs274(prog, rs274=_flaky_rs274(tmp_path, 3))
    assert (tmp_path / "count").read_text().strip() == "3"  # bounded: 3 runs


@needs_rs274
def test_rs274_runs_at_the_same_time_all_end(tmp_path: Path):
    # 4 at once, 4 times each: with one shared $HOME/.tool.mmap about 1 run in 4 was cut short
    prog = tmp_path / "p.ngc"
    prog.write_text(_rs274.random_program(3))
    alone = _rs274.run_rs274(prog)
    outs = []

    def runs():
        for _ in range(4):
            outs.append(_rs274.run_rs274(prog))

    threads = [threading.Thread(target=runs) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=120)
    assert not any(t.is_alive() for t in threads)
    assert len(outs) == 16 and all(o == alone for o in outs)
    assert "PROGRAM_END()" in alone
