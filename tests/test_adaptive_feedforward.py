"""The adaptive loop's anticipation (issue 29): the pass's predicted load from its stock
(rig.adaptive.predict), the cutter's place from one anchor and the overrides since, and the
override set ahead of a step (rig.adaptive.feedforward). References: the end-mill model's own
steady slot force (analysis.forces.evenness), the ball's contact radius in closed form, and
kinematics by hand."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from rig.adaptive.feedforward import FeedForward
from rig.adaptive.predict import PCT_GRID, LoadProfile, campaign_profile
from rig.campaign import load_campaign
from rig.campaign.programs import generate_program

ROOT = Path(__file__).resolve().parent.parent
R_MM = 15.0  # the phi 30 ball


@pytest.fixture(scope="module")
def short_campaign(tmp_path_factory: pytest.TempPathFactory):  # noqa: ANN201
    """adaptive-step.toml on 30 mm of two steps, 0.4 and 0.7 mm (15 mm each)."""
    tmp = tmp_path_factory.mktemp("ff")
    text = (ROOT / "configs" / "campaigns" / "adaptive-step.toml").read_text()
    text = text.replace('output_dir = "data/campaigns"', f"output_dir = {json.dumps(str(tmp))}")
    text = text.replace("block_length_mm = 100.0", "block_length_mm = 30.0")
    text = text.replace("step_depths_mm = [0.1, 0.25, 0.4, 0.55, 0.7]",
                        "step_depths_mm = [0.4, 0.7]")  # fmt: skip
    p = tmp / "short.toml"
    p.write_text(text)
    c = load_campaign(p)
    test = next(t for t in c.tests if t.group == "adaptive")
    cut = generate_program(c.spec.program, test, c.tool, c.machine.dialect, test.name)
    profile, why = campaign_profile(c, test, cut)
    assert profile is not None, why
    return c, test, profile, cut


def test_profile_steady_steps_and_first_contact(short_campaign) -> None:
    from analysis.forces.evenness import SteadyCut, feed_plane_force_n

    c, _, prof, _ = short_campaign
    # the cutter's whole leading half on one step (its contact radius 7.3 mm at 0.4 + 0.3):
    # the steady slot of that depth
    for x, depth in ((7.0, 0.4), (24.0, 0.7)):
        want = feed_plane_force_n(c.tool, c.material.endmill, SteadyCut(depth, 1.0), 2000.0,
                                  np.array([1000.0, 500.0]))  # fmt: skip
        got = prof.force_at(np.array([x, x]), np.array([100.0, 50.0]))
        assert got == pytest.approx(want, rel=0.01)
    # first contact: the ball's edge at the block's face, x = -sqrt(2 r d - d^2) for d = 0.4
    x0 = -math.sqrt(2 * R_MM * 0.4 - 0.4**2)
    assert prof.force_at(x0 - 0.15, 100.0) == 0.0
    assert prof.force_at(x0 + 0.3, 100.0) > 0.0
    # the force grows with the feed at every cutting position
    cutting = prof.force_n[:, 0] > 1.0
    assert (np.diff(prof.force_n[cutting], axis=1) > 0).all()


def test_no_prediction_without_a_stock_model(short_campaign) -> None:
    c, test, _, cut = short_campaign
    post = dataclasses.replace(test, feed_mode="post-processed")
    profile, why = campaign_profile(c, post, cut)
    assert profile is None and "post-processed" in why
    profile, why = campaign_profile(c, test, None)  # dnc send: no program geometry
    assert profile is None and "not known" in why


def _linear_profile() -> LoadProfile:
    """200 N at 100 % from x = 0 to 50 mm, the force proportional to the override."""
    x = np.arange(-10.0, 60.05, 0.1)
    f = np.where((x >= 0) & (x <= 50), 200.0, 0.0)[:, None] * PCT_GRID[None, :] / 100.0
    return LoadProfile(x, f, 1000.0, 2000.0, -10.0, 60.0, "test")


def test_position_follows_the_overrides_grbl_runs() -> None:
    ff = FeedForward(_linear_profile(), 150.0, 30.0, 0.05)
    ff.anchor_t_s, ff.anchor_x_mm = 1.0, 2.0
    ff.commanded(1.5, 200)  # GRBL runs 200 % from 1.5 s
    ff.commanded(2.0, 50)
    v = 1000.0 / 60.0  # mm/s at 100 %
    assert ff.x_at(1.5) == pytest.approx(2.0 + 0.5 * v)
    assert ff.x_at(2.5) == pytest.approx(2.0 + 0.5 * v + 0.5 * 2 * v + 0.5 * 0.5 * v)
    assert ff.ran_over(1.6, 1.9) == 200 and ff.ran_over(1.6, 2.1) is None


def test_anchor_fits_the_entry(short_campaign) -> None:
    """Revolutions made from the prediction itself 4 % stronger (the twin's force differs from
    the catalogue's coefficients): the fitted place within a fifth of a revolution's feed."""
    _, _, prof, _ = short_campaign
    ff = FeedForward(prof, 150.0, 30.0, 0.05)
    rev_s, v = 0.03, 1000.0 / 60.0
    seen, x_end = None, -7.0  # revolutions in the air, then the entry
    for k in range(40):
        x_end = -7.0 + k * v * rev_s
        xs = np.linspace(x_end - v * rev_s, x_end, 31)
        m = 1.04 * float(prof.force_at(xs, 100.0).mean()) + 2.5  # + the noise's |Fxy|
        seen = ff.on_revolution(1.0 + k * rev_s, m, m >= 30.0)
        if seen is not None:
            break
    assert seen is not None and "anchored" in seen
    assert ff.anchor_t_s == pytest.approx(1.0 + k * rev_s)
    assert ff.anchor_x_mm == pytest.approx(x_end, abs=0.1)


def test_override_set_ahead_of_the_step(short_campaign) -> None:
    """Approaching the 0.7 mm step at the 0.4 mm step's override: the lower override is asked
    for while the cutter is still short of where the force rises, by GRBL's delay and half a
    read, and its predicted force is the target."""
    _, _, prof, _ = short_campaign
    ff = FeedForward(prof, 150.0, 30.0, 0.05)
    ff.anchor_t_s, ff.anchor_x_mm = 0.0, 8.0
    p0, _ = prof.pct_for(8.0, 150.0, 10, 200)
    ff.commanded(0.0, p0)
    v = 1000.0 / 60.0 * p0 / 100.0
    t = 0.0
    while (w := ff.want(t, p0, 10, 200, 3.75, 0.015)) is None:
        t += 0.015
        assert t < 2.0
    new, why = w
    x_now = ff.x_at(t)
    x_run = x_now + v * (0.05 + 0.0075)
    assert prof.force_at(x_run, p0) > 150.0 * 1.0375  # where GRBL runs it, too strong at p0
    assert prof.force_at(x_now, p0) <= 150.0 * 1.0375 + 1.0  # not yet where the byte goes out
    assert new < p0 and prof.force_at(x_run, new) == pytest.approx(150.0, rel=0.02)
    assert "feed-forward" in why
