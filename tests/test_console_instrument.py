"""What the console publishes as an instrument (issue 32): the lobes' chatter frequency and the
stability margin beside the spectrum's detected peak, the logger's health, the executed path
for the 3-D view.

Expected values come from outside the console: the shipped campaign's own figures (its comment:
the lobes' limit at 5500 rpm), a tone put into the samples, counts of the blocks handed over,
positions written into the status.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from analysis.runs import file as rf
from rig.console.ring import RingWriter
from rig.daq import DaqInfo

ROOT = Path(__file__).resolve().parent.parent
ORIGIN = {"origin": "http://127.0.0.1"}
WS = "ws://127.0.0.1/ws"


def _client(app: Any) -> Any:
    from starlette.testclient import TestClient

    return TestClient(app, base_url="http://127.0.0.1",
                      headers={"authorization": f"Bearer {app.state.token}"})  # fmt: skip


def _live_folder(tmp_path: Path) -> tuple[Path, RingWriter]:
    folder = tmp_path / "camp"
    (folder / "runs").mkdir(parents=True)
    w = RingWriter(tmp_path / "live.ring")
    (folder / "live.json").write_text(json.dumps({"ring": str(w.path), "pid": os.getpid()}))
    return folder, w


def _meta(rate_hz: float, **extra: Any) -> dict[str, Any]:
    return {"campaign": "t", "run": 1, "runs": 1, "name": "a", "channels": ["Fx", "Fy", "Fz"],
            "rate_hz": rate_hz, "t0_s": 0.0, "sample_format": rf.SAMPLE_FORMAT_VOLTS,
            "scaling_coeff": None, "volts_to_n": (np.eye(3) * 100.0).tolist(),
            "zero_v": [0.0, 0.0, 0.0], "program": []} | extra  # fmt: skip


def _case(config: str) -> dict[str, Any]:
    from rig.campaign import load_campaign, plan_campaign
    from rig.console.chatter import stability_case

    c = load_campaign(ROOT / "configs" / "campaigns" / config)
    return stability_case(c, plan_campaign(c)[0].test)


def _spectra(ws: Any, w: RingWriter, until: Any, timeout_s: float = 60.0) -> dict[str, Any]:
    t_end = time.monotonic() + timeout_s
    while time.monotonic() < t_end:
        w.heartbeat()
        m = ws.receive_json()
        sp = m.get("spectrum")
        if sp is not None and until(sp):
            return sp
    raise AssertionError("no such spectrum")


def test_the_lobes_chatter_frequency_and_margin_beside_the_detected_peak(tmp_path: Path) -> None:
    from rig.console.server import make_app

    # The shipped chatter campaign: a 3-flute slot 0.9 mm deep at 5500 rpm, its tool's modes at
    # 700 Hz; its comment gives the lobes' limit there as about 0.75 mm.
    case = _case("adaptive-chatter.toml")
    assert case["teeth"] == 3 and case["depth_mm"] == 0.9 and case["spindle_rpm"] == 5500.0
    folder, w = _live_folder(tmp_path)
    rate = 10_000.0
    w.begin_run(_meta(rate, spindle_rpm=5500.0, teeth=3, stability=case), 3, np.dtype(np.float64))
    n = 8000  # 0.8 s: 73 revolutions
    t = np.arange(n) / rate
    tooth = sum(np.cos(2 * np.pi * h * 275.0 * t) / h for h in (1, 2, 3))  # 3 x 5500 / 60 Hz
    fx = 2.0 + tooth + 0.8 * np.sin(2 * np.pi * 703.0 * t)  # chatter put in at 703 Hz
    w.write(0, np.vstack([fx, 0.5 * fx, np.zeros(n)]))
    w.put_status({"phase": "running", "machine": {"spindle_rpm": 5500.0}})
    with _client(make_app(folder)) as client, client.websocket_connect(WS, headers=ORIGIN) as ws:
        sp = _spectra(ws, w, lambda s: "depth_limit_mm" in s["stability"])
        # the speed changes (the spindle override): the lobes follow it, to a stable pocket
        w.put_status({"phase": "running", "machine": {"spindle_rpm": 4675.0}})
        moved = _spectra(ws, w, lambda s: s["stability"].get("rpm") == 4675.0)
    w.close(unlink=True)
    st = sp["stability"]
    assert st["depth_limit_mm"] == pytest.approx(0.746, rel=0.03)  # the campaign's comment
    assert 690 < st["predicted_hz"] < 720 and sp["chatter_hz"] == st["predicted_hz"]
    assert st["depth_mm"] == 0.9 and st["stable"] is False
    assert st["depth_pct"] == pytest.approx(100 * 0.9 / st["depth_limit_mm"], abs=0.1)
    assert sp["tooth_hz"] == pytest.approx(275.0) and sp["f_hz"][-1] >= 1.25 * 700
    peak = sp["peak"]
    assert abs(peak["peak_hz"] - 703.0) < 2.0 and peak["judged"] and peak["chatter"]
    # 4675 rpm, the pocket the spindle loop goes to: limit about 3 mm, the 0.9 mm cut stable
    ms = moved["stability"]
    assert ms["depth_limit_mm"] > 2.0 and ms["stable"] is True and ms["depth_pct"] < 50


def test_a_tool_without_modes_says_there_are_no_lobes(tmp_path: Path) -> None:
    from rig.campaign import load_campaign, plan_campaign
    from rig.console.chatter import stability_case

    text = (ROOT / "tests" / "data" / "campaign" / "quick.toml").read_text()
    cfg = tmp_path / "q.toml"
    cfg.write_text(text.replace('"OUT"', json.dumps(str(tmp_path))).replace("FAULTS", ""))
    c = load_campaign(cfg)
    case = stability_case(c, plan_campaign(c)[0].test)
    assert case == {"reason": case["reason"]} and "no modes" in case["reason"]


def _writer(path: Path, rate: float, queue_blocks: int = 64) -> Any:
    from rig.log import RunWriter

    info = DaqInfo("test", ("t/ai0",), ("Fx",), rate, rf.SAMPLE_FORMAT_VOLTS, 10.0, 100)
    w = RunWriter(path, info, clock=lambda: 0.0, queue_blocks=queue_blocks)
    w.on_start(info, 0.0)
    return w


def test_logger_health_is_the_rate_achieved_and_the_samples_written(tmp_path: Path) -> None:
    from rig.console.health import LoggerHealth

    rate, block = 1000.0, 100  # blocks of 0.1 s
    # A healthy logger: every block delivered on time and written.
    w = _writer(tmp_path / "a.h5", rate)
    h = LoggerHealth(rate, 0.0)
    for k in range(30):  # 3 s
        w.on_block(k * block, np.zeros((1, block)))
        h.on_block(block, (k + 1) * block / rate)
        assert w.wait_idle()
        st = h.status(w.stats(), (k + 1) * block / rate)
    w.close()
    assert st["achieved_hz"] == 1000.0 and st["written_pct"] == 100.0 and st["judged"]
    assert not st["flag"] and st["received"] == 3000 and st["written"] == 3000
    # A DAQ that loses every tenth block (overflows): 900 samples a second delivered.
    w = _writer(tmp_path / "b.h5", rate)
    h = LoggerHealth(rate, 0.0)
    for k in range(30):
        if k % 10 != 9:
            w.on_block(k * block, np.zeros((1, block)))
            h.on_block(block, (k + 1) * block / rate)
        st = h.status(w.stats(), (k + 1) * block / rate)
    w.close()
    assert st["achieved_hz"] == pytest.approx(2700 / 2.9, abs=0.1)  # the last block lost
    assert st["flag"] and "sample rate" in st["why"]
    # A writer that stalls (a slow disk): its queue of 4 blocks fills, the rest are dropped.
    w = _writer(tmp_path / "c.h5", rate, queue_blocks=4)
    h = LoggerHealth(rate, 0.0)
    with w.hold():
        for k in range(30):
            w.on_block(k * block, np.zeros((1, block)))
            h.on_block(block, (k + 1) * block / rate)
            st = h.status(w.stats(), (k + 1) * block / rate)
    w.close()
    assert st["achieved_hz"] == 1000.0 and st["lost"] > 0
    assert st["written_pct"] < 95.0 and st["flag"] and "written" in st["why"]
    # nothing judged before 2 s of run clock
    assert not LoggerHealth(rate, 0.0).status(None, 0.5)["judged"]


def test_the_executed_path_comes_with_feed_and_force(tmp_path: Path) -> None:
    from rig.console.server import make_app
    from rig.console.trail import MAX_GAP_S

    folder, w = _live_folder(tmp_path)
    rate = 1000.0
    w.begin_run(_meta(rate), 3, np.dtype(np.float64))
    w.write(0, np.vstack([np.full(500, 0.3), np.full(500, 0.4), np.zeros(500)]))  # 30, 40 N
    with _client(make_app(folder)) as client, client.websocket_connect(WS, headers=ORIGIN) as ws:
        got: list[list[Any]] = []
        for k in range(12):  # the machine moves 1 mm along X each 0.2 s, feed 300 mm/min
            w.put_status({"t_now_s": 0.2 * k, "machine": {"pos_mm": [float(k), 2.0, -1.0],
                                                          "feed_mm_min": 300.0}})  # fmt: skip
            w.heartbeat()
            t_end = time.monotonic() + 10
            while len(got) <= k and time.monotonic() < t_end:
                m = ws.receive_json()
                if "trail" in m:
                    tr = m["trail"]
                    got = tr["points"] if tr["reset"] else got + tr["points"]
        # the same position again, soon after: no new point
        w.put_status({"t_now_s": 2.3, "machine": {"pos_mm": [11.0, 2.0, -1.0]}})
        for _ in range(10):
            m = ws.receive_json()
            assert "trail" not in m or not m["trail"]["points"]
    w.close(unlink=True)
    assert [p[1:4] for p in got] == [[float(k), 2.0, -1.0] for k in range(12)]
    assert [p[0] for p in got] == pytest.approx([0.2 * k for k in range(12)])
    assert all(p[4] == 300.0 and p[5] == pytest.approx(50.0, abs=0.01) for p in got)  # |(30, 40)|
    assert MAX_GAP_S > 0.3
