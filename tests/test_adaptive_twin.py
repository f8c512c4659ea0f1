"""The adaptive loop on the twin (issue 29): the real streamer over a real pty to the simulated
GRBL 1.1, the simulated DAQ and real HDF5 run files, through the campaign runner.

Safety cases (c): over-force and a lost force signal each end in a feed hold (then the run is
stopped as an interlock), with every sample kept; the step-depth demonstration (a). All slow
(each a campaign run of 15 s or more on the busy 2-core machine).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from analysis.runs import file as rf
from rig.campaign import load_campaign, run_campaign

ROOT = Path(__file__).resolve().parent.parent
SHIPPED = ROOT / "configs" / "campaigns" / "adaptive-step.toml"
REV_S = 60.0 / 2000  # the cut's revolution


def _config(tmp_path: Path, short: bool = True, **adaptive: object) -> Path:
    """The shipped campaign with its output in ``tmp_path`` (``short``: 30 mm of two steps,
    0.4 and 0.7 mm) and ``[adaptive]`` fields replaced."""
    text = SHIPPED.read_text()
    text = text.replace(
        'output_dir = "data/campaigns"', f"output_dir = {json.dumps(str(tmp_path))}"
    )
    if short:
        text = text.replace("block_length_mm = 100.0", "block_length_mm = 30.0")
        text = text.replace("step_depths_mm = [0.1, 0.25, 0.4, 0.55, 0.7]",
                            "step_depths_mm = [0.4, 0.7]")  # fmt: skip
    for k, v in adaptive.items():
        line = f"{k} = {json.dumps(v)}"
        text, n = re.subn(rf"^{k} = .*$", line, text, flags=re.M)
        if not n:
            text = text.replace("[adaptive]\n", f"[adaptive]\n{line}\n")
    p = tmp_path / "adaptive.toml"
    p.write_text(text)
    return p


def _events(run: rf.Run) -> list[tuple[str, str, float]]:
    ev = run.events
    return list(zip(ev["kind"], ev["message"], ev["time_s"].astype(float), strict=True))


def _adaptive_run(tmp_path: Path, **adaptive: object) -> tuple[object, rf.Run]:
    c = load_campaign(_config(tmp_path, **adaptive))
    res = run_campaign(c, progress=False, only=lambda t: t.group == "adaptive")
    (r,) = res.runs
    return r, rf.load_run(r.file)


def _nothing_lost(run: rf.Run) -> None:
    """Every sample of the run kept, on one unbroken device clock, to after the stop."""
    assert run.samples_lost == 0
    kinds = set(run.events["kind"])
    assert not kinds & {rf.EV_GAP, rf.EV_OVERFLOW, rf.EV_QUEUE_FULL}
    dt = np.diff(run.time_s)
    assert np.allclose(dt, 1.0 / run.rate_hz, rtol=1e-6)


@pytest.mark.slow
@pytest.mark.faults
def test_over_force_holds_within_a_revolution(tmp_path: Path) -> None:
    # max 200 N on the resultant: the 0.4 mm step's teeth reach about 250 N at 100 % feed
    r, run = _adaptive_run(tmp_path, max_force_n=200)
    assert r.status == rf.STATUS_ABORT
    assert "adaptive interlock" in r.reason and "above max_force_n 200 N" in r.reason
    ev = _events(run)
    holds = [(m, t) for k, m, t in ev if k == rf.EV_PAUSE and m.startswith("adaptive:")]
    assert len(holds) == 1 and "feed hold" in holds[0][0]
    assert any(k == rf.EV_INTERLOCK for k, _, _ in ev)
    # the hold comes within one revolution of the first sample above the limit (the record's
    # own forces: the DAQ read that carried it ends at most 0.015 s later)
    res = np.linalg.norm(run.force_n, axis=1)
    t_over = float(run.time_s[np.argmax(res > 200)])
    assert 0 <= holds[0][1] - t_over <= REV_S
    _nothing_lost(run)
    assert run.time_s[-1] >= holds[0][1]  # recorded through the hold to the stop


@pytest.mark.slow
@pytest.mark.faults
def test_signal_loss_holds_and_resets(tmp_path: Path) -> None:
    # the controller hears nothing from 1.0 s after the program starts (the recording goes on)
    r, run = _adaptive_run(tmp_path, sim_signal_loss_at_s=1.0)
    assert r.status == rf.STATUS_ABORT and "force signal lost" in r.reason
    ev = _events(run)
    t_start = next(t for k, m, t in ev if m.startswith("adaptive: feed, target"))
    (t_hold,) = [t for k, m, t in ev if k == rf.EV_PAUSE and "signal lost" in m]
    stall_s = 0.015 + 3 * REV_S  # one DAQ read plus stall_revs revolutions
    # the limit counts from the last block heard, which ends up to one read (0.015 s) before
    # the loss; the watchdog polls every 2 ms of wall time (0.02 s at 10 x speed)
    assert stall_s - 0.015 <= t_hold - (t_start + 1.0) <= stall_s + 0.05
    _nothing_lost(run)


@pytest.mark.slow
def test_step_depth_adaptive_feed_holds_the_target(tmp_path: Path) -> None:
    """Seed 001's block at 150 N: the 0.1 mm step is out of reach (its load is the edge's: 74 N
    at 200 %), the controller reports it saturated, and the share within +-10 % is given over
    all the cutting time and over the reachable time apart. The loop anticipates each step from
    the block's stock (feed-forward), the measured force correcting the rest."""
    from rig.adaptive.session import target_of
    from rig.report.adaptive_figures import (
        adaptive_events,
        cycle_time_s,
        saturated_spans,
        within_band,
    )
    from rig.report.base import load_runs

    c = load_campaign(_config(tmp_path, short=False))
    res = run_campaign(c, progress=False, only=lambda t: t.group in ("baseline", "adaptive"))
    assert res.ok
    runs, _ = load_runs(res.folder)
    base, ad = (next(lr for lr in runs if lr.group == g) for g in ("baseline", "adaptive"))
    wb, wa = within_band(base, 150.0), within_band(ad, 150.0)
    # measured on 4 seeds (2003-2006) with the feed-forward, GRBL's 40-50 ms from byte to
    # motion: all the cutting time 0.916, 0.914, 0.916, 0.914; the reachable time 0.973, 0.972,
    # 0.973, 0.970; 16 revolutions (0.48 s) saturated at 200 %; the baseline 0.195 (feedback
    # only, before: 0.765-0.787 and 0.815-0.841). Of seed 2003's 273 revolutions 23 miss: 20 on
    # the 0.1 mm step (its entry and 74-75 N at 200 %), 1 entering the 0.25 mm step, 2 at the
    # exit. The seeds' spread is under one revolution in 273 (0.0037), so the bounds are the
    # lowest less four revolutions' share (0.014); the baseline's plus a quarter.
    assert wa["within"] >= 0.90
    assert wa["within_reachable"] >= 0.955
    assert wb["within"] <= 0.25
    (span,) = saturated_spans(ad.run)
    assert 14 <= wa["saturated_revolutions"] <= 20
    # the span lies on the 0.1 mm step: the first 20 mm of the 100 mm block, at 200 % feed
    # (2000 mm/min: 0.6 s) from the cut's first revolution (3.0 s into the program, +-0.1 s)
    assert 2.9 <= span[0] and span[1] <= 3.0 + 0.6 + 0.1
    assert cycle_time_s(ad.run) > cycle_time_s(base.run)  # the deep steps ran slower
    # the report's adaptive list says the same, both shares and the saturated time
    from rig.report.adaptive import adaptive_entries

    (e,), md = adaptive_entries(c, runs)
    assert e["within_10pct"] == wa["within"] and e["baseline_within_10pct"] == wb["within"]
    assert e["within_10pct_reachable"] == wa["within_reachable"]
    assert e["saturated_s"] == pytest.approx(wa["saturated_revolutions"] * REV_S)
    assert e["target_force_n"] == 150.0 and e["target_from"] == "[adaptive] target_force_n"
    assert e["feed_forward"] is True
    notes = [m for _, _, m in adaptive_events(ad.run)]
    assert any("; feed-forward: the step-depth block's stock (5 steps)" in m for m in notes)
    assert sum("feed-forward: anchored at x = " in m for m in notes) == 1
    assert "within (reachable)" in md and "saturated s" in md
    # the default target (no target_force_n): the feed rule's reference cut, a 0.7 mm slot at
    # 1000 mm/min, as the material's coefficients predict it, against what the baseline measured
    # on its 0.7 mm step (its last 20 mm: the revolutions before the 4.6 mm exit)
    test = next(t for t in c.tests if t.group == "adaptive")
    no_target = c.spec.model_copy(update={"adaptive": c.spec.adaptive.model_copy(
        update={"target_force_n": None})})  # fmt: skip
    import dataclasses

    predicted, _ = target_of(dataclasses.replace(c, spec=no_target), test)
    measured = float(np.median(wb["means"][-35:-15]))
    assert predicted == pytest.approx(measured, rel=0.03)


@pytest.mark.slow
def test_step_depth_reachable_holds_the_target_90pct(tmp_path: Path) -> None:
    """configs/campaigns/adaptive-step-reachable.toml: the block without its 0.1 mm step, every
    step within the override's reach of 150 N: the issue's 0.90 over all the cutting time, the
    steps anticipated from the block's stock (feedback only, GRBL's 40-50 ms from byte to motion
    and the step entries kept it at 0.857-0.881)."""
    from rig.report.adaptive_figures import within_band
    from rig.report.base import load_runs

    text = (ROOT / "configs" / "campaigns" / "adaptive-step-reachable.toml").read_text()
    p = tmp_path / "reachable.toml"
    p.write_text(text.replace('output_dir = "data/campaigns"',
                              f"output_dir = {json.dumps(str(tmp_path))}"))  # fmt: skip
    res = run_campaign(load_campaign(p), progress=False)
    assert res.ok
    runs, _ = load_runs(res.folder)
    base, ad = (next(lr for lr in runs if lr.group == g) for g in ("baseline", "adaptive"))
    wb, wa = within_band(base, 150.0), within_band(ad, 150.0)
    # measured on 4 seeds (2003-2006): 0.981, 0.984, 0.981, 0.981 (none saturated); the baseline
    # 0.241-0.243. Bound: the lowest less three revolutions' share of 320 (0.01; the seeds'
    # spread is one revolution).
    assert wa["within"] >= 0.97 and wa["saturated_revolutions"] == 0
    assert wa["within_reachable"] == wa["within"]
    assert wb["within"] <= 0.30


@pytest.mark.slow
def test_live_console_status_shows_the_loop(tmp_path: Path) -> None:
    """The live ring's status carries the loop's target, force per revolution and overrides."""
    import threading

    from rig.console import live_console

    c = load_campaign(_config(tmp_path))
    seen: list[dict] = []
    with live_console(c, serve=False) as live:
        done = threading.Event()

        def poll() -> None:
            while not done.wait(0.01):
                _, st = live.ring.get_json("status")
                a = (st or {}).get("adaptive")
                if a and a.get("force_n") is not None:
                    seen.append(a)

        th = threading.Thread(target=poll, daemon=True)
        th.start()
        try:
            run_campaign(c, progress=False, only=lambda t: t.group == "adaptive",
                         **live.run_kwargs())  # fmt: skip
        finally:
            done.set()
            th.join(5.0)
    assert seen, "no adaptive status in the live ring"
    assert {a["target_force_n"] for a in seen} == {150.0} and seen[0]["mode"] == "feed"
    assert any(a["feed_pct"] != 100 for a in seen)  # the loop moved the feed override


@pytest.mark.slow
def test_chatter_moves_the_spindle_to_a_pocket_and_clears(tmp_path: Path) -> None:
    """Issue 29 (b): configs/campaigns/adaptive-chatter.toml, a 0.9 mm slot at 5500 rpm."""
    from analysis.chatter import indicators

    text = (ROOT / "configs" / "campaigns" / "adaptive-chatter.toml").read_text()
    p = tmp_path / "chatter.toml"
    p.write_text(text.replace('output_dir = "data/campaigns"',
                              f"output_dir = {json.dumps(str(tmp_path))}"))  # fmt: skip
    res = run_campaign(load_campaign(p), progress=False)
    assert res.ok
    base, loop = (rf.load_run(r.file) for r in res.runs)
    ev = [(t, m) for k, m, t in _events(loop) if m.startswith("adaptive:")]
    (t_move,) = [t for t, m in ev if "spindle to the stable pocket 4675 rpm (85 %)" in m]
    (t_clear,) = [t for t, m in ev if "chatter cleared" in m]
    revs = (t_clear - t_move) * 4675 / 60
    # the controller's own verdict (analysis.chatter.live): a window of 20 revolutions at the new
    # speed (from when GRBL turns at it, 40-50 ms after the bytes) is the least it can judge,
    # then a verdict per 0.1 s (7.8 revolutions); measured 25 on 4 seeds
    assert 20 <= revs <= 30

    # the record, judged by the detector apart from the loop: from 20 revolutions after the
    # move to the end of the cut, the loop's slot is stable and the baseline's still chatters
    def judged(run: rf.Run, rpm: float) -> bool:
        m = (run.time_s > t_move + 20 * 60 / rpm) & (run.time_s < t_move + 0.45)
        return indicators(run.force_n[m][:, :2], run.rate_hz, rpm, floor_n=30).chatter

    assert not judged(loop, 4675.0)
    assert judged(base, 5500.0)

    # the physics (rig.report.adaptive_figures.chatter_decay): the force's part off the spindle
    # harmonics per revolution after the move's bytes, below the detector's energy threshold
    # (0.1) for 20 revolutions from the 8th-10th revolution on 4 seeds (3.5-4 of them GRBL's
    # 40-50 ms before the spindle turns at the new speed; the live watch 25 each); bound: the
    # highest plus the spread. The baseline, judged the same from the same time, never clears.
    from rig.report.adaptive import adaptive_entries
    from rig.report.adaptive_figures import chatter_decay
    from rig.report.base import load_runs

    c = load_campaign(p)
    runs, _ = load_runs(res.folder)
    (e,), _ = adaptive_entries(c, runs)
    assert e["chatter_cleared_revs"] is not None and 0 <= e["chatter_cleared_revs"] <= 12
    assert 20 <= e["chatter_cleared_live_revs"] <= 30
    t_bytes = float(re.search(r"at ([0-9.]+) s;", next(m for t, m in ev if t == t_move)).group(1))
    assert chatter_decay(base, t_bytes, 5500.0)["cleared_revs"] is None
