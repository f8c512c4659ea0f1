"""The campaign runner on the simulated rig: real ptys, the real streamer, real HDF5 run files.

Faults end with valid files, the reason recorded and a resumable campaign; Ctrl-C and a killed
process too; a real rig that is absent is refused before anything runs.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from analysis.errors import CutlabError
from analysis.runs import file as rf
from rig.campaign import campaign_status, load_campaign, run_campaign

DATA = Path(__file__).parent / "data" / "campaign"
ROOT = Path(__file__).resolve().parent.parent


def _config(tmp_path: Path, faults: str = "", name: str = "quick.toml") -> Path:
    text = (DATA / "quick.toml").read_text()
    text = text.replace('"OUT"', json.dumps(str(tmp_path / "out"))).replace("FAULTS", faults)
    p = tmp_path / name
    p.write_text(text)
    return p


def _runs(result):  # noqa: ANN001, ANN202
    return {r.index: r for r in result.runs}


@pytest.mark.long
def test_campaign_runs_records_everything_and_resumes(tmp_path: Path) -> None:
    c = load_campaign(_config(tmp_path))
    res = run_campaign(c, progress=False)
    assert res.ok and [r.status for r in res.runs] == ["success", "success"]
    run = rf.load_run(res.runs[1].file)
    assert run.complete and run.status == "success" and run.samples_lost == 0
    cond = run.conditions
    assert cond["depth_mm"] == 2.0 and cond["fz_mm"] == 0.3 and cond["tool"] == "seed003-facemill"
    assert cond["material"] == "al6061-t6" and cond["software_version"]
    assert run.rig["calibration_id"] == c.rig.dynamometer.calibration_id
    assert run.program_info["sha256"] == cond["program_sha256"]
    assert "G1 X" in run.program_text and len(run.blocks) == run.program_text.count("\n")
    assert run.blocks["send_s"].is_monotonic_increasing
    kinds = list(run.events["kind"])
    assert "zero" in kinds and kinds[-1] == "stop"
    # The cut is in the record: forces of hundreds of newtons while the program ran.
    assert run.force_n[:, 0].max() > 100
    manifest = json.loads((res.folder / "campaign.json").read_text())
    assert {e["status"] for e in manifest["runs"].values()} == {"success"}
    # Running again skips what is finished.
    again = run_campaign(load_campaign(_config(tmp_path)), progress=False)
    assert all(r.skipped for r in again.runs) and again.ok


def test_status_of_a_campaign_that_has_not_run_lists_every_run_missing(tmp_path: Path) -> None:
    c = load_campaign(_config(tmp_path))
    st = campaign_status(c, tmp_path / "elsewhere")
    assert st["campaign"] == c.name and st["folder"] == str(tmp_path / "elsewhere" / c.name)
    assert [(r["run"], r["status"]) for r in st["runs"]] == [(0, "missing"), (1, "missing")]


@pytest.mark.long
def test_controller_that_stops_answering_fails_the_run_and_resume_reruns_it(
    tmp_path: Path,
) -> None:
    cfg = _config(tmp_path, "sim_controller_stall_after_block = 5\nsim_fault_run = 0")
    # The campaign's watchdog (1 s of wall time past the expected end) must see the stall before
    # the DNC link's own timeout does, also on loaded cores: give the link a wide margin.
    text = cfg.read_text().replace("link_timeout_s = 1.5", "link_timeout_s = 5.0")
    cfg.write_text(text + "\n[suspenders]\nwatchdog_wall_s = 1.0\n")
    res = run_campaign(load_campaign(cfg), progress=False)
    r = _runs(res)
    assert r[0].status == "fail" and "stopped answering" in r[0].reason
    assert r[1].status == "success"  # the campaign went on
    run0 = rf.load_run(r[0].file)
    assert run0.complete and run0.status == "fail" and run0.reason == r[0].reason
    assert (run0.events["kind"] == "fault").any()
    # The fault is cleared (the controller answers again): resume re-runs run 0 only and keeps
    # the failed attempt's file.
    res2 = run_campaign(load_campaign(_config(tmp_path)), progress=False)
    r2 = _runs(res2)
    assert r2[0].status == "success" and not r2[0].skipped and r2[1].skipped
    kept = list((res.folder / "runs").glob("000-*.attempt-1.h5"))
    assert len(kept) == 1 and rf.load_run(kept[0]).status == "fail"


def test_daq_overflow_fails_the_run_with_the_sample_index(tmp_path: Path) -> None:
    cfg = _config(tmp_path, "sim_daq_overflow_at_s = 1.0\nsim_fault_run = 1")
    res = run_campaign(load_campaign(cfg), progress=False)
    r = _runs(res)
    assert r[0].status == "success"
    assert r[1].status == "fail" and "overflow at sample 8000" in r[1].reason
    run = rf.load_run(r[1].file)
    assert run.status == "fail" and run.samples_lost > 0
    ev = run.events[run.events["kind"] == "overflow"]
    assert list(ev["sample"]) == [8000]


def test_interlock_trip_aborts_with_the_reason(tmp_path: Path) -> None:
    cfg = _config(tmp_path, "sim_interlock_at_s = 2.0\nsim_fault_run = 0")
    res = run_campaign(load_campaign(cfg), progress=False)
    r = _runs(res)
    assert r[0].status == "abort" and "interlock" in r[0].reason
    run = rf.load_run(r[0].file)
    assert run.complete and (run.events["kind"] == "interlock").any()
    assert r[1].status == "success"


def _cli(args: list[str]) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "rig.cli", *args], cwd=ROOT, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True,
    )  # fmt: skip


def _wait_for(pred, timeout_s: float = 60.0) -> None:  # noqa: ANN001
    t0 = time.monotonic()
    while not pred():
        if time.monotonic() - t0 > timeout_s:
            raise AssertionError("timed out")
        time.sleep(0.05)


def _streaming(folder: Path) -> bool:
    m = folder / "campaign.json"
    try:
        runs = json.loads(m.read_text())["runs"]
    except (OSError, ValueError, KeyError):
        return False
    return any(e.get("status") == "running" for e in runs.values())


def _program_started(folder: Path) -> bool:
    """The run being written (read live, SWMR) has samples and its program is streaming."""
    from analysis.runs import RunFollower

    files = sorted((folder / "runs").glob("*.h5"))
    try:
        with RunFollower(files[0]) as fol:
            _, volts, events = fol.poll()
    except (IndexError, OSError, rf.RunFileError, KeyError):
        return False  # not created (or not readable) yet
    return len(volts) > 0 and bool((events["kind"] == "start").any())


@pytest.mark.long
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGINT])
def test_killed_or_interrupted_campaign_leaves_valid_files_and_resumes(
    tmp_path: Path, sig: signal.Signals
) -> None:
    cfg = _config(tmp_path)
    text = cfg.read_text().replace("speed = 50", "speed = 4")  # slow enough to be caught mid-run
    cfg.write_text(text)
    folder = tmp_path / "out" / "quick"
    p = _cli(["campaign", "run", str(cfg), "--quiet", "--no-report"])
    try:
        _wait_for(lambda: _streaming(folder) and _program_started(folder))
        p.send_signal(sig)
        _, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
    files = sorted((folder / "runs").glob("*.h5"))
    assert files
    run = rf.load_run(files[0])  # opens after SIGKILL too (repaired: plain h5py opens it)
    if sig == signal.SIGKILL:
        assert p.returncode == -signal.SIGKILL
        assert run.status == "interrupted" and not run.complete and run.samples_stored > 0
        st = campaign_status(load_campaign(cfg))["runs"][0]
        assert st["status"] == "interrupted" and f"{run.samples_stored} samples" in st["reason"]
        manifest = json.loads((folder / "campaign.json").read_text())
        assert manifest["runs"][st["name"]]["status"] == "interrupted"
    else:
        assert p.returncode == 130, err
        assert run.complete and run.status == "abort" and "Ctrl-C" in run.reason
        assert (run.events["kind"] == "pause").any()
    # Resume: the interrupted run is cut again, the earlier file kept; the campaign completes.
    cfg.write_text(text.replace("speed = 4", "speed = 50"))
    res = run_campaign(load_campaign(cfg), progress=False)
    assert res.ok
    assert list((folder / "runs").glob("000-*.attempt-1.h5"))


@pytest.mark.long
def test_missing_real_hardware_is_refused_before_anything_runs(tmp_path: Path) -> None:
    cfg = _config(tmp_path)
    cfg.write_text(cfg.read_text().replace('rig = "sim"', 'rig = "real"'))
    with pytest.raises(CutlabError) as e:
        run_campaign(load_campaign(cfg), progress=False)
    msg = str(e.value)
    assert "DAQ" in msg and "serial" in msg and "/dev/ttyUSB0" in msg
    assert not (tmp_path / "out").exists()
    p = _cli(["campaign", "run", str(cfg), "--dry-run", "--json"])
    out, err = p.communicate(timeout=60)
    assert p.returncode == 2
    d = json.loads(out)
    assert not d["ok"] and d["programs_checked"] == 2 and len(d["problems"]) == 2
    p = _cli(["campaign", "run", str(cfg)])
    out, err = p.communicate(timeout=60)
    # on a loaded host the heartbeat ("...: working, 11 s") may come before the refusal
    lines = [ln for ln in err.splitlines() if ": working, " not in ln]
    assert p.returncode == 2 and "Traceback" not in err, err
    assert len(lines) == 1 and lines[0].startswith("cutlab: error:"), err


def test_grbl_machine_streams_with_acknowledgements(tmp_path: Path) -> None:
    cfg = _config(tmp_path)
    cfg.write_text(cfg.read_text().replace('machine = "ace-h63"', 'machine = "lab-grbl"'))
    res = run_campaign(load_campaign(cfg), progress=False)
    assert res.ok
    run = rf.load_run(res.runs[0].file)
    assert "O1001" not in run.program_text and "N10" not in run.program_text
    b = run.blocks
    assert b["ack_s"].notna().all() and (b["ack_s"] >= b["send_s"]).all()
    assert run.force_n[:, 0].max() > 100


def test_force_limit_suspender_holds_the_feed_and_aborts(tmp_path: Path) -> None:
    cfg = _config(tmp_path)
    text = cfg.read_text().replace("speed = 50", "speed = 10")  # lag under load costs less
    cfg.write_text(text + '\n[suspenders]\nforce_limit_n = 250\non_force = "hold"\n')
    res = run_campaign(load_campaign(cfg), progress=False)
    for r in res.runs:
        assert r.status == "abort" and "above the limit 250 N" in r.reason
        run = rf.load_run(r.file)
        pauses = run.events[run.events["kind"] == "pause"]
        assert len(pauses) == 1 and "feed hold" in pauses["message"].iloc[0]
        # The hold came within a few revolutions of the first force above the limit, and the
        # spindle stopped after the abort (no force at the end of the record).
        resultant = np.linalg.norm(run.force_n, axis=1)
        t_over = run.time_s[np.argmax(resultant > 250)]
        # A DAQ read is 0.1 s; a busy CPU can delay the simulated DAQ a little more.
        assert 0 <= pauses["time_s"].iloc[0] - t_over < 1.0
        assert resultant[-int(0.05 * run.rate_hz) :].mean() < 20


def test_every_sample_can_be_tied_to_its_executed_block(tmp_path: Path) -> None:
    import re

    res = run_campaign(load_campaign(_config(tmp_path)), progress=False)
    run = rf.load_run(res.runs[0].file)
    notes = run.events[run.events["message"].str.startswith("executed block")]
    spans = []
    for m in notes["message"]:
        g = re.match(r"executed block (\d+) ([\d.]+)\.\.([\d.]+) s: (.*)", m)
        spans.append((float(g[2]), float(g[3]), g[4]))
    cut = [s for s in spans if s[2].startswith("N70 G1 X")]
    assert len(spans) == len(run.blocks) and len(cut) == 1
    t0, t1, _ = cut[0]
    # The forces are there while the cutting block runs, and not before it starts.
    f = np.linalg.norm(run.force_n, axis=1)
    during = (run.time_s > t0) & (run.time_s < t1)
    before = run.time_s < t0 - 0.05
    assert f[during].max() > 300 and f[before].max() < 20


def test_operator_pause_is_a_feed_hold_and_resume_continues_the_cut(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import threading

    import rig.campaign.run as runmod
    from rig.campaign.run import StopRequest
    from rig.campaign.tap import RunTap

    answered = threading.Event()

    def resume_after_a_while(prompt: str) -> bool:
        time.sleep(0.3)  # the operator looks at the machine, then presses cycle start
        answered.set()
        return True

    monkeypatch.setattr(runmod, "_ask_resume", resume_after_a_while)
    cfg = _config(tmp_path)
    cfg.write_text(cfg.read_text().replace("speed = 50", "speed = 2"))
    c = load_campaign(cfg)
    stop = StopRequest()
    pressed = threading.Event()
    on_block = RunTap.on_block

    def press_ctrl_c_during_the_cut(tap, first_sample: int, data) -> None:  # noqa: ANN001
        on_block(tap, first_sample, data)
        if tap.peak_force_n > 100.0 and not pressed.is_set():  # the insert is in the cut
            pressed.set()
            stop.request()

    monkeypatch.setattr(RunTap, "on_block", press_ctrl_c_during_the_cut)
    res = run_campaign(c, progress=False, stop=stop, only=lambda t: t.index == 0)
    assert pressed.is_set() and answered.is_set()
    r = res.runs[0]
    assert r.status == "success", r.reason
    run = rf.load_run(r.file)
    kinds = list(run.events["kind"])
    assert "pause" in kinds and "resume" in kinds
    t_pause = run.events.loc[run.events["kind"] == "pause", "time_s"].iloc[0]
    t_resume = run.events.loc[run.events["kind"] == "resume", "time_s"].iloc[0]
    assert t_resume - t_pause > 0.4  # 0.3 s wall at 2x
    # Held: the feed stopped, so the chip vanished and only ploughing remains on the insert.
    f = np.linalg.norm(run.force_n, axis=1)
    held = (run.time_s > t_pause + 0.15) & (run.time_s < t_resume - 0.05)
    cutting = (run.time_s > t_resume + 0.2) & (run.time_s < t_resume + 0.6)
    assert f[held].max() < 0.8 * f[cutting].max()
    # Never a rewind: the cutting block ran to its programmed end after the resume.
    notes = run.events[run.events["message"].str.contains("N70 G1 X")]
    assert len(notes) == 1 and float(notes["message"].iloc[0].split("..")[1].split()[0]) > t_resume
