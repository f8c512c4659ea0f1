"""Campaign analysis and report against the simulator's truth (seeded, simulated rig)."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from analysis.config import get_material
from rig.campaign import load_campaign, run_campaign
from rig.report import write_report

DATA = Path(__file__).parent / "data" / "campaign"


@pytest.mark.long
def test_facemill_campaign_identifies_the_truth_and_writes_the_report(tmp_path: Path) -> None:
    text = (DATA / "quick.toml").read_text().replace('"OUT"', f'"{tmp_path / "out"}"')
    text = text.replace("FAULTS", "hum_n = 0.0").replace("block_length_mm = 10.0",
                                                          "block_length_mm = 16.0")  # fmt: skip
    text = text.replace("depth_mm = [1.0, 2.0]", "depth_mm = [0.5, 1.5, 3.0]")
    text = text.replace('identify_groups = ["g"]', 'identify_groups = ["g"]\n'
                        'validate_groups = ["v"]')  # fmt: skip
    text += '\n[[matrix]]\ngroup = "v"\nspindle_rpm = 1200\nfz_mm = 0.4\ndepth_mm = 2.0\n'
    cfg = tmp_path / "fm.toml"
    cfg.write_text(text)
    res = run_campaign(load_campaign(cfg), progress=False)
    assert res.ok
    rep = write_report(res.folder)
    s = rep.summary["facemill-coefficients"]
    assert s["success"], s["message"]
    truth = get_material("al6061-t6").facemill
    # The noise is seeded ([sim] seed + run index). The record's start (when the streamed program
    # reaches the control) varies with the machine's load and moves the revolution grid against
    # the cut; it used to move the face mill's long entry and exit tails into the "air" that the
    # offset line is drawn through (P_R off by 13.7 %, or a run rejected). Now the tails count
    # as cutting; what the grid's phase still moves (a partly engaged revolution in or out of
    # the window) is not in the bootstrap over runs and revolutions: trimming 0..400 samples off
    # the start of the same recorded runs (every phase of the grid) moved the coefficients by
    # at most 0.34 %, so the truth lies in the 95 % bootstrap interval widened by that
    # measured phase effect (the noise-only standard error, 0.3 % on P_R, would not hold it).
    # One feed: the edge (ploughing) terms are not separable from the cutting ones by design, and
    # the report says so on their line; since the twin's dynamometer answers between samples and
    # each height of an insert enters the block on its own ray (issue 33), P_R reads +4.7 % here
    # where the sample-rate twin matched the fit exactly. Identified ones hold 2 %.
    # The status is the design's (analysis.identify.facemill_split): one feed over 50 mm, the
    # K's are the feed's force per mm of depth, not split from the P's.
    status = {r["coefficient"]: r["status"] for r in s["coefficients"]}
    assert status["K_T_n_mm2"].startswith("identified as force per depth only (one feed)")
    assert status["P_R_n_mm"].startswith("not identified"), status
    phase_rel = 0.0034
    for r in s["coefficients"][:4]:
        truth_value = getattr(truth, r["coefficient"])
        if not str(r.get("status", "identified")).startswith("identified"):
            assert r["coefficient"].startswith("P_"), r
            continue
        lo, hi = r["boot_ci_low"], r["boot_ci_high"]
        assert lo - phase_rel * abs(lo) <= truth_value <= hi + phase_rel * abs(hi), r
        assert r["identified"] == pytest.approx(truth_value, rel=0.02), r
    identified = [abs(r["error_pct"]) for r in s["coefficients"]
                  if str(r.get("status", "identified")).startswith("identified")]  # fmt: skip
    assert identified and max(identified) < 2.0, s["coefficients"]
    assert s["validation_max_abs_error_pct"] < 3.0
    for f in ("report.md", "summary.json", "runs.csv", "coefficients.csv", "validation.csv",
              "force_traces.png", "fit_vs_depth.png", "predicted_vs_measured.png"):  # fmt: skip
        assert (rep.folder / f).stat().st_size > 0, f
    runs = pd.read_csv(rep.folder / "runs.csv")
    assert list(runs["status"]) == ["success"] * 4
    assert json.loads((rep.folder / "summary.json").read_text())["runs"] == 4
    assert "| K_T_n_mm2 |" in rep.markdown


@pytest.mark.long
def test_afc_post_processed_feeds_shorten_the_cut_and_even_the_force(tmp_path: Path) -> None:
    c = load_campaign("afc-step-depth")
    res = run_campaign(c, out_root=tmp_path, progress=False)
    assert res.ok
    s = write_report(res.folder).summary["afc-compare"]
    assert s["time_saving_pct"] >= 30.0  # seed 001: about 40 %
    assert s["program_time_saving_pct"] >= 40.0
    assert s["cv_adjusted"] < 0.5 * s["cv_constant"]
    # The simulated cut cannot beat what the model says any feeds within the limits reach (the
    # 0.03 allows for noise and the transitions between steps the bound leaves out) ...
    assert s["cv_ratio"] >= s["bound_least_cv_ratio_at_this_saving"] - 0.03
    # ... and the issue's two targets (CV ratio 1/3, 30 % shorter) meet just outside seed 001's
    # 3500 mm/min maximum feed.
    assert not s["bound_targets_reachable"]
    assert 3500 < s["bound_max_feed_for_both_targets_mm_min"] < 3600
    assert (Path(res.folder) / "report" / "feed_limit_bound.png").stat().st_size > 10_000


@pytest.mark.slow
def test_feed_sweep_finds_seed001_base_feed_and_writes_a_rule(tmp_path: Path) -> None:
    from analysis.rules import load_rule

    res = run_campaign(load_campaign("feed-sweep"), out_root=tmp_path, progress=False)
    assert res.ok
    s = write_report(res.folder).summary["feed-rule"]
    assert s["success"] and s["base_feed_mm_min"] == 1000.0
    rule = load_rule(s["rule_file"])
    assert rule.base_feed_mm_min == 1000.0 and len(rule.feeds_mm_min) == 20
