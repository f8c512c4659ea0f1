"""Kill trials: `cutlab campaign run` killed with SIGKILL at random moments, then resumed.

After each kill and resume, every run is either complete and like the same run of an uninterrupted
campaign (same conditions and program, no lost samples, the same cut forces within the simulated
rig's noise), or an earlier attempt kept beside it that reads ``interrupted`` with every sample
it holds readable, and opens in plain h5py. 3 trials in the fast tier, 50 in the slow one.
"""

from __future__ import annotations

import json
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from analysis.runs import file as rf
from rig.campaign import load_campaign, run_campaign

pytestmark = pytest.mark.faults
DATA = Path(__file__).parent / "data" / "campaign"
ROOT = Path(__file__).resolve().parent.parent


def _config(folder: Path) -> Path:
    text = (DATA / "quick.toml").read_text()
    text = text.replace('"OUT"', json.dumps(str(folder / "out"))).replace("FAULTS", "")
    p = folder / "quick.toml"
    p.write_text(text)
    return p


def _cut_force_n(run: rf.Run) -> float:
    """Mean resultant force where the insert cuts (above 100 N), N."""
    f = np.linalg.norm(run.force_n, axis=1)
    return float(f[f > 100.0].mean())


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> dict[int, rf.Run]:
    """The same campaign, never interrupted."""
    res = run_campaign(load_campaign(_config(tmp_path_factory.mktemp("ref"))), progress=False)
    assert res.ok
    return {r.index: rf.load_run(r.file) for r in res.runs}


def _trial(
    folder: Path, moment: tuple[str, float], reference: dict[int, rf.Run]
) -> tuple[bool, int]:
    """One kill and resume; (killed, interrupted attempts found). ``moment``: ("start", s after
    the command started) or ("recording", s after the first run file appeared)."""
    cfg = _config(folder)
    proc = subprocess.Popen(
        [sys.executable, "-m", "rig.cli", "campaign", "run", str(cfg), "--quiet", "--no-report"],
        cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
    )  # fmt: skip
    runs_dir = folder / "out" / "quick" / "runs"
    try:
        phase, delay_s = moment
        try:
            if phase == "recording":  # wherever the machine's load puts the recordings
                t0 = time.monotonic()
                while (proc.poll() is None and not any(runs_dir.glob("*.h5"))
                       and time.monotonic() - t0 < 120):  # fmt: skip
                    time.sleep(0.01)
            proc.wait(timeout=delay_s)
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode in (0, -signal.SIGKILL), proc.stderr.read().decode()[-2000:]
    res = run_campaign(load_campaign(cfg), progress=False)  # resume
    assert res.ok, [(r.status, r.reason) for r in res.runs]
    for r in res.runs:
        run, ref = rf.load_run(r.file), reference[r.index]
        assert run.complete and run.status == "success" and run.samples_lost == 0
        assert run.conditions["program_sha256"] == ref.conditions["program_sha256"]
        assert {k: run.conditions[k] for k in ("depth_mm", "fz_mm", "spindle_rpm")} == {
            k: ref.conditions[k] for k in ("depth_mm", "fz_mm", "spindle_rpm")
        }
        assert _cut_force_n(run) == pytest.approx(_cut_force_n(ref), rel=0.03)
    for attempt in runs_dir.glob("*.attempt-*.h5"):
        run = rf.load_run(attempt)
        assert run.status == "interrupted" and not run.complete, (attempt, run.status)
        assert np.isfinite(run.volts).all()
        with h5py.File(attempt, "r") as f:  # repaired: plain h5py opens it
            assert rf.samples_dataset(f).shape[0] == run.samples_stored
    manifest = json.loads((res.folder / "campaign.json").read_text())
    assert {e["status"] for e in manifest["runs"].values()} == {"success"}
    return proc.returncode == -signal.SIGKILL, len(list(runs_dir.glob("*.attempt-*.h5")))


def _kill_moments(n: int, seed: int) -> list[tuple[str, float]]:
    """One in five during start-up (imports, planning, ptys: about 4 s on an idle 2-core
    machine), the rest over the two recordings and the end (about 1.6 s from the first file)."""
    rng = random.Random(seed)
    return [("start", rng.uniform(0.3, 4.0)) if rng.random() < 0.2
            else ("recording", rng.uniform(0.0, 1.8)) for _ in range(n)]  # fmt: skip


# The kill during a recording (the interrupted attempt kept and repaired) in the quick tier; the
# kill at start-up and the later one, the same kill-and-resume path, in CI's command (long).
@pytest.mark.parametrize("moment", [
    pytest.param(("start", 2.0), marks=pytest.mark.long),
    ("recording", 0.3),
    pytest.param(("recording", 1.1), marks=pytest.mark.long),
], ids=["moment0", "moment1", "moment2"])  # fmt: skip
def test_kill_and_resume_fast(tmp_path: Path, reference, moment: tuple[str, float]) -> None:
    _trial(tmp_path, moment, reference)


@pytest.mark.slow
def test_kill_and_resume_50_trials(tmp_path: Path, reference) -> None:
    t0 = time.monotonic()
    killed = mid_run = 0
    for k, moment in enumerate(_kill_moments(50, 2019)):
        folder = tmp_path / f"trial{k:02d}"
        folder.mkdir()
        was_killed, attempts = _trial(folder, moment, reference)
        killed += was_killed
        mid_run += attempts > 0
    print(f"50 kill trials in {time.monotonic() - t0:.0f} s: {killed} killed, {mid_run} while a "
          "run was recording")
    # the moments do reach the recordings (19-23 of 50 seen, fewer under load; a run closed just
    # before the kill is adopted on resume, not kept as an attempt)
    assert mid_run >= 15
