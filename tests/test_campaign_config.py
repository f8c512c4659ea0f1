"""Campaign files: matrix expansion, shipped campaigns, bad input refused before anything runs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from analysis.config import get_tool
from analysis.errors import ConfigError
from rig.campaign import plan_campaign
from rig.campaign.config import MatrixEntry, expand_matrix, load_campaign
from rig.campaign.programs import generate_program

BASE = """
[campaign]
name = "t"
machine = "ace-h63"
tool = "{tool}"
material = "al6061-t6"
rig = "{rig}"

[program]
kind = "{kind}"
{program_extra}

[[matrix]]
group = "g"
spindle_rpm = {rpm}
{feed}
depth_mm = {depth}
"""


def _write(tmp_path: Path, **kw: object) -> Path:
    args = dict(tool="seed003-facemill", rig="sim", kind="facemill-pass", program_extra="",
                rpm=600, feed="fz_mm = 0.236", depth="[0.5, 1.0]")  # fmt: skip
    args.update(kw)
    p = tmp_path / "c.toml"
    p.write_text(BASE.format(**args))
    return p


def test_matrix_is_the_product_of_lists() -> None:
    tool = get_tool("phi10-flat")
    e = MatrixEntry(group="a", spindle_rpm=[1000, 2000], fz_mm=[0.05, 0.1, 0.15], depth_mm=2.0,
                    width_mm=[5.0, 10.0])  # fmt: skip
    tests = expand_matrix((e,), tool)
    assert len(tests) == 2 * 3 * 2
    assert len({t.name for t in tests}) == len(tests)
    t = tests[0]
    assert t.feed_mm_min == pytest.approx(t.fz_mm * tool.flutes * t.spindle_rpm)
    # Feed given in mm/min gives the feed per tooth back.
    e2 = MatrixEntry(group="b", spindle_rpm=2000, feed_mm_min=[400, 600], depth_mm=0.3)
    t2 = expand_matrix((e2,), get_tool("phi30-ball"))
    assert [t.fz_mm for t in t2] == pytest.approx([400 / 4000, 600 / 4000])
    assert t2[0].width_mm == 30.0  # a slot by default


@pytest.mark.parametrize("name", ["facemill-ploughing", "feed-sweep", "afc-step-depth"])
def test_shipped_campaigns_load_and_plan(name: str) -> None:
    c = load_campaign(name)
    plans = plan_campaign(c)
    assert len(plans) == len(c.tests) >= 2
    for p in plans:
        assert p.program_text.strip().endswith("M30")
        assert p.expected_s > 0


def test_seed003_matrix() -> None:
    c = load_campaign("facemill-ploughing")
    ident = [t for t in c.tests if t.group == "identify"]
    assert [t.depth_mm for t in ident] == [0.5, 1.0, 1.5, 2.0, 2.5, 3.0]
    assert {t.fz_mm for t in ident} == {0.236}
    assert {t.fz_mm for t in c.tests if t.group.startswith("validate-0")} == {0.246, 0.345}


def test_feed_above_machine_max_is_refused_with_file_and_line(tmp_path: Path) -> None:
    p = _write(tmp_path, rpm=8000, feed="fz_mm = 2.0", depth="1.0")
    with pytest.raises(ConfigError) as e:
        load_campaign(p)
    msg = str(e.value)
    assert f"{p}:" in msg and "16000 mm/min" in msg and "feed_max_mm_min = 10000" in msg
    assert f"{p}:16: test 0 (g): feed = 16000" in msg  # the fz_mm line of the [[matrix]]


def test_a_problem_shared_by_many_tests_is_said_once_at_its_field(tmp_path: Path) -> None:
    p = _write(tmp_path, rpm="[600, 700, 800]", depth="15.0")
    with pytest.raises(ConfigError) as e:
        load_campaign(p)
    lines = str(e.value).splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(f"{p}:17: tests 0-2 (g): depth_mm = 15 is beyond the usable insert")


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (dict(tool="phi10-flat", kind="slot", feed="fz_mm = 0.05", depth="30", rpm=3000),
         r"depth_mm = 30 is beyond the flute length .*22 mm"),
        (dict(depth="[1.0, 15.0]"), r"depth_mm = 15 is beyond the usable insert edge"),
        (dict(tool="phi99-unicorn"), r"campaign.tool = 'phi99-unicorn'.*known tools"),
        (dict(program_extra="block_lenght_mm = 20"), r"program.block_lenght_mm.*unknown key"),
        (dict(feed="fz_mm = -0.1"), r"fz_mm = -0.1: must be > 0"),
        (dict(rig="simulated"), r"campaign.rig = 'simulated'"),
        (dict(kind="slot"), "needs an end mill"),
        (dict(program_extra="\n[analysis]\ncv_ratio_target = 2"),
         r"c\.toml:13: analysis\.cv_ratio_target = 2: .*less than or equal to 1"),
    ],
    ids=["beyond-flute", "beyond-insert", "unknown-tool", "unknown-key", "negative-fz",
         "unknown-rig", "wrong-tool-for-program", "cv-target-above-1"],
)  # fmt: skip
def test_bad_campaign_is_refused_naming_field_and_value(
    tmp_path: Path, change: dict, message: str
) -> None:
    with pytest.raises(ConfigError, match=message):
        load_campaign(_write(tmp_path, **change))


def test_generated_programs_parse_and_cut_where_intended() -> None:
    from planning.nc import interpret

    c = load_campaign("facemill-ploughing")
    t = c.tests[0]
    cut = generate_program(c.spec.program, t, c.tool, "fanuc")
    m = interpret(cut.text, c.machine)
    feed_moves = np.isclose(m.end[:, 2], -t.depth_mm)
    assert feed_moves.any()
    # The cutter reaches depth in the air, before the block (x < -R).
    first = int(feed_moves.argmax())
    assert m.end[first, 0] < -c.tool.radius_mm
    grbl = generate_program(c.spec.program, t, c.tool, "grbl")
    assert "N10" not in grbl.text and "O1001" not in grbl.text
    interpret(grbl.text, c.machine, dialect="grbl")


def test_dry_run_warns_when_tooth_passing_meets_a_dynamometer_mode(tmp_path: Path) -> None:
    from rig.campaign import dry_run

    # 8000 rpm x 3 flutes = 400 Hz; its 5th harmonic (2000 Hz) sits on the 2050 Hz X mode.
    p = _write(tmp_path, tool="phi10-flat", kind="slot", rpm=8000, feed="fz_mm = 0.05",
               depth="2.0")  # fmt: skip
    d = dry_run(load_campaign(p))
    assert d.ok and any("2050 Hz" in w and "harmonic 5" in w for w in d.warnings)
    # Seed 003's 600 rpm with one insert is far below every mode (seed 003 3.2).
    assert dry_run(load_campaign("facemill-ploughing")).warnings == []
