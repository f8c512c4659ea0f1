"""Axes from the physics (issue 27, item 2): ``--axes auto`` and the refusal of a mapping that
gives a negative cutting coefficient or fits clearly worse, on cuts made by the independent
simulator (tests/_force_sim.py, no fitting code) in its own frame (x feed, y cross-feed, z up;
forces on the workpiece), which is cutlab's. Slots and partial-immersion cuts, so that x and y
are separable; each of the 48 signed permutations of the columns a mounting could give."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from analysis.config import get_tool
from analysis.errors import AnalysisError
from analysis.identify import ForceRun, RunConditions, reduce_run
from analysis.identify.axes import AxisMap, check_axes, choose_axes, remap
from rig.cli import main
from tests._trust_exports import RATE_HZ, RPM, TRUTH, export, record

DESIGN = (("slot", 10.0, 0.03), ("slot", 10.0, 0.05), ("slot", 10.0, 0.08),
          ("down", 3.0, 0.04), ("down", 3.0, 0.07), ("up", 3.0, 0.05))  # fmt: skip
COLUMNS = ("Fx", "Fy", "Fz")
MOUNTINGS = [(p, s) for p in itertools.permutations(range(3))
             for s in itertools.product((1.0, -1.0), repeat=3)]  # fmt: skip


def _matrix(perm, signs) -> np.ndarray:
    """Column k of the file = signs[k] x true axis perm[k]."""
    m = np.zeros((3, 3))
    for k, (p, s) in enumerate(zip(perm, signs)):
        m[k, p] = s
    return m


@pytest.fixture(scope="module")
def averages():
    out = []
    for k, (mode, ae, fz) in enumerate(DESIGN):
        c = RunConditions(spindle_rpm=RPM, fz_mm=fz, depth_mm=2.0, width_mm=ae, mode=mode)
        out.append(reduce_run(ForceRun(f"{mode}{ae:g}_{fz:g}", record(fz, mode, ae, k),
                                       RATE_HZ, c), 3))  # fmt: skip
    return out


def test_auto_finds_every_mounting_or_refuses_never_a_wrong_one(averages):
    tool = get_tool("phi10-flat")
    base = AxisMap(COLUMNS)
    found = 0
    for perm, signs in MOUNTINGS:
        m = _matrix(perm, signs)
        mounted = [remap(a, m) for a in averages]
        try:
            chosen, info = choose_axes(mounted, tool, base)
        except AnalysisError:
            continue
        # the chosen mapping takes the file's columns back to the simulator's frame
        assert np.array_equal(chosen.matrix(COLUMNS, "t") @ m, np.eye(3)), (perm, signs)
        assert info["chosen"]["coefficients"]["Ktc"] == pytest.approx(TRUTH["Ktc_n_mm2"], 0.02)
        found += 1
    assert found == 48  # this design tells every mounting


def test_explicit_mappings_other_than_the_right_one_are_refused(averages):
    tool = get_tool("phi10-flat")
    accepted = []
    for perm, signs in MOUNTINGS:
        axes = AxisMap(tuple(COLUMNS[p] for p in perm), signs)  # type: ignore[arg-type]
        # the columns hold the true frame; read under ``axes`` they become this
        read = [remap(a, axes.matrix(COLUMNS, "t")) for a in averages]
        if check_axes(read, tool, axes)["refusal"] is None:
            accepted.append(axes.text)
    assert accepted == ["x=Fx,y=Fy,z=Fz"]


def test_slots_alone_cannot_tell_x_from_y(averages):
    with pytest.raises(AnalysisError, match="cannot tell .* give --axes"):
        choose_axes(averages[:3], get_tool("phi10-flat"), AxisMap(COLUMNS))


@pytest.fixture(scope="module")
def turned(tmp_path_factory):
    """The design's exports from a dynamometer turned: its Fx is the cutter's -y, its Fy the x,
    its Fz the -z."""
    d = tmp_path_factory.mktemp("turned")
    m = _matrix((1, 0, 2), (-1.0, 1.0, -1.0))
    return [str(export(d, fz, mode, ae, k, matrix=m)) for k, (mode, ae, fz) in enumerate(DESIGN)]


@pytest.mark.faults
def test_cli_auto_picks_the_mapping_and_refuses_a_wrong_one(turned, capsys):
    files = turned
    args = ["analyze", "forces", *files, "--model", "endmill", "--tool", "phi10-flat"]
    rc = main([*args, "--axes", "auto", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["axes"] == "x=Fy,y=-Fx,z=-Fz"
    assert out["coefficients"]["Ktc"] == pytest.approx(TRUTH["Ktc_n_mm2"], rel=0.02)
    assert "runner-up" in out["axes_choice"]["line"]
    rc = main([*args, "--axes", "auto"])
    text = capsys.readouterr().out
    assert rc == 0 and "axes auto: x=Fy,y=-Fx,z=-Fz: Ktc 79" in text and "runner-up" in text
    # the default mapping (columns by name) and a wrong explicit one: refused, one line
    for extra in ([], ["--axes", "x=-Fx,y=-Fy,z=-Fz"]):
        rc = main([*args, *extra])
        cap = capsys.readouterr()
        assert rc == 2 and cap.out == "" and len(cap.err.strip().splitlines()) == 1, extra
        assert "the runs fit x=Fy,y=-Fx,z=-Fz" in cap.err and "Validation" not in cap.err
    # slots alone: auto cannot tell x from y
    rc = main([*args[:3], *files[:3], *args[-4:], "--axes", "auto"])
    cap = capsys.readouterr()
    assert rc == 2 and "cannot tell" in cap.err and "give --axes" in cap.err


@pytest.mark.faults
def test_data_import_axes_auto_writes_the_chosen_mapping(turned, tmp_path, capsys):
    files = turned
    common = ["--tool", "phi10-flat", "--axes", "auto"]
    rc = main(["data", "import", *files[:3], *common, "-o", str(tmp_path / "slots")])
    cap = capsys.readouterr()
    assert rc == 2 and "cannot tell" in cap.err and not (tmp_path / "slots").exists()
    rc = main(["data", "import", *files, *common, "-o", str(tmp_path / "runs"), "--json"])
    cap = capsys.readouterr()
    written = json.loads(cap.out)["written"]
    assert rc == 0 and {w["axes"] for w in written} == {"x=Fy,y=-Fx,z=-Fz"}
    assert "data import: axes auto: x=Fy,y=-Fx,z=-Fz" in cap.err and "runner-up" in cap.err
    runs = sorted(str(p) for p in (tmp_path / "runs").glob("*.h5"))
    rc = main(["analyze", "forces", *runs, "--tool", "phi10-flat", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["coefficients"]["Ktc"] == pytest.approx(TRUTH["Ktc_n_mm2"], rel=0.02)
