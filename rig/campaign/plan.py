"""A campaign's plan: every test's program generated (the feed post-processor over it where the
test asks for it) and checked before anything runs."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

from analysis.errors import ConfigError, CutlabError
from rig.campaign.config import Campaign, RunConditions
from rig.campaign.programs import CutProgram, generate_program


@dataclass(frozen=True)
class PlannedRun:
    """A test with its program, ready to run. ``expected_s``: machine time of the program, s."""

    test: RunConditions
    cut: CutProgram
    program_text: str
    file_stem: str
    expected_s: float
    sha256: str


def _dialect(campaign: Campaign) -> str:
    if campaign.spec.campaign.rig == "sim" and campaign.spec.sim.protocol:
        return campaign.spec.sim.protocol
    return campaign.machine.dialect


def _post_process(text: str, campaign: Campaign, test: RunConditions, cut: CutProgram) -> str:
    """The feed post-processor (planning.feed.post, seed 001) over a generated program."""
    from analysis.forces import ENDMILL
    from analysis.rules import load_rule
    from rig.campaign.programs import campaign_rule, post_process_program

    tool = campaign.tool
    if not ENDMILL.describes(tool):
        raise ConfigError(f"{campaign.path}: post-processed feeds need an end mill")
    if test.rule == "campaign":
        if campaign.spec.feed_rule is None:
            raise ConfigError(
                f"{campaign.path}: test {test.index}: rule = 'campaign' needs a [feed_rule] table"
            )
        rule = campaign_rule(campaign.spec, tool, f"{campaign.name}-rule")
        piece = campaign.spec.feed_rule.min_piece_mm
    else:
        p = Path(test.rule or "")
        rule = load_rule(p if p.is_absolute() else campaign.path.parent / p)
        piece = 2.0
    out, _ = post_process_program(cut, tool, rule, campaign.machine, piece)
    return out


def plan_campaign(campaign: Campaign) -> list[PlannedRun]:
    """Generate and check every test's program; the problems of all of them are raised together
    (one ConfigError, a line each) before anything runs."""
    out, problems = [], []
    dialect = _dialect(campaign)
    for t in campaign.tests:
        try:
            out.append(_plan_one(campaign, t, dialect))
        except CutlabError as exc:
            where = f"{campaign.path}:{t.source_line}" if t.source_line else str(campaign.path)
            problems += [f"{where}: test {t.index} ({t.name}): {line}"
                         for line in str(exc).splitlines()]  # fmt: skip
    if problems:
        raise ConfigError("\n".join(dict.fromkeys(problems)))
    return out


def _plan_one(campaign: Campaign, t: RunConditions, dialect: str) -> PlannedRun:
    from rig.dnc import program_from_text

    cut = generate_program(campaign.spec.program, t, campaign.tool, dialect, t.name)
    text = cut.text
    if t.feed_mode == "post-processed":
        text = _post_process(text, campaign, t, cut)
    stem = f"{t.index:03d}-{t.name}"
    program_from_text(text, f"{stem}.nc")
    sha = hashlib.sha256(text.encode()).hexdigest()
    return PlannedRun(t, cut, text, stem, _expected_seconds(cut, campaign), sha)


def _expected_seconds(cut: CutProgram, campaign: Campaign) -> float:
    plunge = (campaign.spec.program.safe_z_mm - cut.z_cut_mm) / min(cut.cut_feed_mm_min, 500.0)
    return 60.0 * (plunge + abs(cut.x_end_mm - cut.x_start_mm) / cut.cut_feed_mm_min) + 1.0
