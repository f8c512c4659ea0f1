"""The adaptive loop's configuration (issue 29): the hard cap from the tool's catalogue entry,
the default target from the campaign's feed rule, and the override path a machine declares
(refused in one line when the loop cannot drive it)."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest

from analysis.config import MachineConfig, get_tool
from analysis.errors import ConfigError
from rig.adaptive.override import override_path, refusal
from rig.adaptive.session import check_adaptive, max_force_of, target_of
from rig.campaign import load_campaign

ROOT = Path(__file__).resolve().parent.parent
STEP = ROOT / "configs" / "campaigns" / "adaptive-step.toml"


def _campaign(tmp_path: Path, drop: tuple[str, ...] = (), name: str = "c.toml"):
    """adaptive-step.toml with the lines ``key = ...`` of ``drop`` removed (and, for
    ``feed_rule``, its whole table and the plan-feed run that needs it)."""
    text = STEP.read_text()
    for key in drop:
        if key == "feed_rule":
            text = re.sub(r"^\[feed_rule\]\n(?:[^\[\n].*\n|\n)*", "", text, flags=re.M)
            text = text[: text.index('[[matrix]]\ngroup = "plan-feed"')]
        else:
            text, n = re.subn(rf"^{key} = .*\n", "", text, flags=re.M)
            assert n, key
    p = tmp_path / name
    p.write_text(text)
    return load_campaign(p)


def test_tools_carry_their_hard_cap() -> None:
    assert get_tool("phi30-ball").max_force_n == 20000
    assert get_tool("phi10-flat").max_force_n == 2200
    assert get_tool("phi20-flat").max_force_n is None  # not given: no cap from the tool


def test_hard_cap_is_the_lowest_given(tmp_path: Path) -> None:
    # the tool's 20 kN, [adaptive] 3 kN, [suspenders] 5 kN: the config may only lower the cap
    assert max_force_of(_campaign(tmp_path)) == 3000
    c = _campaign(tmp_path, ("max_force_n",))
    assert max_force_of(c) == 5000
    c = _campaign(tmp_path, ("max_force_n", "force_limit_n"))
    assert max_force_of(c) == 20000  # the tool's own


def test_default_target_is_the_rule_reference_load(tmp_path: Path) -> None:
    from analysis.forces.evenness import SteadyCut, feed_plane_force_n

    c = _campaign(tmp_path, ("target_force_n",))
    test = next(t for t in c.tests if t.group == "adaptive")
    target, why = target_of(c, test)
    # the rule's reference cut: a 0.7 mm slot at 1000 mm/min, 2000 rpm; seed 001's measure
    ref = feed_plane_force_n(c.tool, c.material.endmill, SteadyCut(0.7, 1.0), 2000.0,
                             np.array([1000.0]))[0]  # fmt: skip
    assert target == pytest.approx(ref, rel=1e-12)
    # the twin's 0.7 mm step measured 235 N at 1000 mm/min (adaptive-step.toml's note): the
    # prediction is the cut's load, not an arbitrary number
    assert target == pytest.approx(235.0, rel=0.03)
    assert "0.7 mm slot at 1000 mm/min" in why
    check_adaptive(c)  # a campaign without target_force_n but with a rule is runnable
    # a given target wins
    assert target_of(_campaign(tmp_path), test)[0] == 150.0


def test_no_target_and_no_rule_is_one_line(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    c = _campaign(tmp_path, ("target_force_n", "feed_rule"))
    with pytest.raises(ConfigError, match=r"\[adaptive\] target_force_n: missing: no "
                       r"target_force_n and no \[feed_rule\]"):  # fmt: skip
        check_adaptive(c)
    from rig.cli import main

    assert main(["campaign", "run", str(tmp_path / "c.toml"), "--out", str(tmp_path)]) == 2
    # (the heartbeat's "working" lines aside) one error line naming the file and the field
    err = [x for x in capsys.readouterr().err.splitlines() if "working," not in x]
    assert len(err) == 1 and "target_force_n: missing" in err[0] and "c.toml" in err[0]


def test_override_path_by_dialect_and_declared() -> None:
    from analysis.config import load_machine as get_machine

    grbl, fanuc = get_machine("lab-grbl"), get_machine("ace-h63")
    assert grbl.override_path == "grbl-realtime" and fanuc.override_path == "none"
    assert override_path(fanuc, "fanuc") == "none" and refusal(grbl, "grbl") is None
    # the twin streams GRBL whatever the machine's dialect: its bytes are the path
    assert refusal(fanuc, "grbl") is None
    wired = fanuc.model_copy(update={"override": "external-analog"})
    assert override_path(wired, "fanuc") == "external-analog"
    assert "external input" in refusal(wired, "fanuc")
    assert "no override path" in refusal(fanuc, "fanuc")
    # a Fanuc cannot claim GRBL's real-time bytes
    data = fanuc.model_dump()
    data["override"] = "grbl-realtime"
    with pytest.raises(ValueError, match="only GRBL 1.1 takes real-time override bytes"):
        MachineConfig.model_validate(data)


def test_campaign_on_a_drip_feed_refuses_naming_the_path(tmp_path: Path) -> None:
    text = STEP.read_text().replace('protocol = "grbl"\n', "")
    text = text.replace('machine = "lab-grbl"', 'machine = "ace-h63"')
    p = tmp_path / "fanuc.toml"
    p.write_text(text)
    c = load_campaign(p)
    with pytest.raises(ConfigError) as e:
        check_adaptive(c)
    msg = str(e.value)
    assert "\n" not in msg and "fanuc.toml: [adaptive]" in msg
    assert "'ace-h63' has no override path" in msg
    wired = dataclasses.replace(
        c, machine=c.machine.model_copy(update={"override": "external-analog"})
    )
    with pytest.raises(ConfigError, match="drives no analog override output yet"):
        check_adaptive(wired)
