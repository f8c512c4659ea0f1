"""What cutlab writes for a machine, that machine's own check accepts (issue 31, item 3).

For every shipped machine config (configs/machines/*.toml) and every command that writes NC
(``plan rough``, ``plan feed``, ``plan orient`` where the machine has rotary axes, the campaign's
program writer), the output passes ``cutlab nc check OUT --machine M``, run through the CLI's
``main`` as a user would. The ``plan feed`` input is Fanuc-style (an O number line), the way
CAM posts write it: a GRBL machine reads that line as its sender does (stripped, not refused).
"""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import pytest

from rig.cli import main

ROOT = Path(__file__).resolve().parent.parent
MACHINES = sorted(p.stem for p in (ROOT / "configs" / "machines").glob("*.toml"))
# planning takes seconds: the default run covers the GRBL machine (the one whose check refused
# its own plans), the slow tier every machine
MACHINE_PARAMS = [m if m == "lab-grbl" else pytest.param(m, marks=pytest.mark.slow)
                  for m in MACHINES]  # fmt: skip

# a Fanuc-style input for plan feed: O number with its comment, decimal points, N words
SLOT = """%
O0431 (SLOT)
N10 G21 G90 G17
N20 S2000 M3
N30 G0 X-20. Y30. Z5.
N40 G1 Z-0.3 F1000
N50 G1 X120.
N60 G0 Z50.
N70 M30
%
"""


def _run(argv: list[str]) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        rc = main(argv)
    return rc, err.getvalue()


def _check(out: Path, machine: str) -> None:
    rc, err = _run(["nc", "check", str(out), "--machine", machine])
    assert rc == 0, f"nc check {out.name} --machine {machine}: {err}"


def test_every_shipped_machine_is_covered() -> None:
    assert {"ace-h63", "lab-grbl", "mill-5axis"} <= set(MACHINES)


@pytest.fixture(scope="module")
def small_part(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from test_rough_parts import bump_grid, part_toml, write_toml

    x, y, z = bump_grid(40, 45, 18, 26, 30, n=7)
    root = tmp_path_factory.mktemp("part")
    return write_toml(root, part_toml(x, y, z, top=43.0, tool="phi10-flat"))


@pytest.mark.long
@pytest.mark.parametrize("dialect", [None, "machine"])
@pytest.mark.parametrize("machine", MACHINE_PARAMS)
def test_plan_rough_output_passes_the_machines_check(
    small_part: Path, tmp_path: Path, machine: str, dialect: str | None
) -> None:
    from analysis.config import load_machine

    out = tmp_path / "r.nc"
    argv = ["plan", "rough", str(small_part), "--machine", machine, "-o", str(out), "--no-png",
            "--no-check"]  # fmt: skip
    if dialect:  # --dialect named as well as implied by --machine: the same program
        argv += ["--dialect", load_machine(machine).dialect]
    rc, err = _run(argv)
    assert rc == 0, err
    _check(out, machine)
    if load_machine(machine).dialect == "grbl":
        assert not any(ln.lstrip().upper().startswith("O") for ln in out.read_text().splitlines())


@pytest.fixture(scope="module")
def rule_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from analysis.rules import derive_rule, save_rule, slot_load_percent

    p = tmp_path_factory.mktemp("rule") / "rule.toml"
    save_rule(derive_rule("rt", 100, 1000, 3500, slot_load_percent("ball", 30, 0.3, 30)), p)
    return p


@pytest.mark.parametrize("machine", MACHINE_PARAMS)
def test_plan_feed_of_a_fanuc_style_input_passes_the_machines_check(
    rule_file: Path, tmp_path: Path, machine: str
) -> None:
    src = tmp_path / "slot.nc"
    src.write_text(SLOT)
    outs = {}
    for extra in ([], ["--dialect", "grbl"]):
        out = tmp_path / f"f{len(extra)}.nc"
        rc, err = _run(["plan", "feed", str(src), "--rules", str(rule_file), "--machine", machine,
                        "--tool", "phi30-ball", "--stock", "box:0,100,0,60,-10,0", "--spacing",
                        "2", "-o", str(out), *extra])  # fmt: skip
        assert rc == 0, err
        outs[tuple(extra)] = out
    _check(outs[()], machine)
    _check(outs[("--dialect", "grbl")], "lab-grbl")


def test_plan_feed_reads_an_o_line_the_same_with_machine_or_dialect(
    rule_file: Path, tmp_path: Path
) -> None:
    """--machine lab-grbl and --dialect grbl (on the default Fanuc machine) write the same
    program from the same Fanuc-style input (the two paths are one)."""
    src = tmp_path / "slot.nc"
    src.write_text(SLOT)
    texts = []
    for opts in (["--machine", "lab-grbl"], ["--dialect", "grbl"]):
        out = tmp_path / f"{opts[1]}.nc"
        rc, err = _run(["plan", "feed", str(src), "--rules", str(rule_file), *opts, "--tool",
                        "phi30-ball", "--stock", "box:0,100,0,60,-10,0", "--spacing", "2", "-o",
                        str(out)])  # fmt: skip
        assert rc == 0, err
        texts.append(out.read_text())
    assert texts[0] == texts[1]
    assert "O0431" not in texts[0]


@pytest.mark.slow
def test_plan_orient_output_passes_the_rotary_machines_check(tmp_path: Path) -> None:
    from test_orient_cli import FAN, small

    from analysis.config import load_machine

    rotary = [m for m in MACHINES if getattr(load_machine(m), "kinematics", None) is not None]
    assert "mill-5axis" in rotary or rotary == []
    cfg = tmp_path / "fan.toml"
    cfg.write_text(small(FAN.read_text(), "[0.5]", 4))
    rc, err = _run(["plan", "orient", str(cfg), "-o", str(tmp_path / "o"), "--no-plot"])
    assert rc == 0, err
    _check(tmp_path / "o" / "program.nc", "mill-5axis")


@pytest.mark.parametrize("machine", MACHINES)
def test_campaign_programs_pass_the_machines_check(tmp_path: Path, machine: str) -> None:
    """The campaign's program writer, for each machine's dialect, over a shipped campaign's
    program section and tests."""
    from analysis.config import load_machine
    from rig.campaign import load_campaign
    from rig.campaign.programs import generate_program

    camp = load_campaign(ROOT / "configs" / "campaigns" / "feed-sweep.toml")
    dialect = load_machine(machine).dialect
    for t in camp.tests[:3]:
        cut = generate_program(camp.spec.program, t, camp.tool, dialect, t.name)
        out = tmp_path / f"{t.index:03d}.nc"
        out.write_text(cut.text)
        _check(out, machine)
