"""The live console without a browser: the shared-memory ring, the server's frames, commands and
run browser (Starlette's TestClient), the command line's bad input.

Expected values come from the generators here (a ramp, a sine, hand-made blocks), not from the
console's own binning.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from analysis.runs import file as rf
from rig.console.ring import RingError, RingReader, RingWriter
from rig.daq import DaqInfo

ROOT = Path(__file__).resolve().parent.parent
RATE_HZ = 1000.0


def _meta(c: int = 3, zero: list[float] | None = None) -> dict:
    return {"campaign": "t", "run": 1, "runs": 2, "name": "a", "channels": ["Fx", "Fy", "Fz"][:c],
            "rate_hz": RATE_HZ, "t0_s": 5.0, "sample_format": rf.SAMPLE_FORMAT_VOLTS,
            "scaling_coeff": None, "volts_to_n": (np.eye(c) * 100.0).tolist(), "zero_v": zero,
            "program": []}  # fmt: skip


def test_ring_round_trip_wraps_and_drops_what_was_overwritten(tmp_path: Path) -> None:
    w = RingWriter(tmp_path / "r.ring", sample_bytes=3 * 8 * 30 * 4)  # 4 slots of 30 rows
    r = RingReader(w.path, mirror_bytes=3 * 4 * 100)  # a history of 100 rows of 3 float32
    w.begin_run(_meta(), 3, np.dtype(np.float64), 30)
    ramp = np.arange(250, dtype=float)
    for k in range(0, 250, 30):  # blocks of 30 samples, the reader's history wraps twice
        n = min(30, 250 - k)
        w.write(k, np.vstack([ramp[k : k + n], -ramp[k : k + n], ramp[k : k + n] * 2]))
        r.pull()  # (the server looks every frame)
    gen, first, offset, rows = r.rows_since(-1, 0)
    assert gen == 1 and first == 150 and offset == 0  # the last 100 rows are left
    assert np.array_equal(rows[:, 0], ramp[150:]) and np.array_equal(rows[:, 1], -ramp[150:])
    gen, first, _, rows = r.rows_since(1, 240)
    assert first == 240 and np.array_equal(rows[:, 2], 2 * ramp[240:])
    # a hole in the device samples: later rows keep their device time
    w.write(300, np.ones((3, 10)))
    _, first, offset, rows = r.rows_since(1, 250)
    assert first == 250 and first + offset == 300 and len(rows) == 10
    # a reader that looked away finds what the 4 slots still hold (blocks from 180 on)
    late = RingReader(w.path)
    _, first, offset, rows = late.rows_since(-1, 0)
    assert first == 0 and len(rows) == 80 and first + offset + len(rows) == 310
    assert np.array_equal(rows[:, 0], np.r_[ramp[180:], np.ones(10)])
    late.close()
    # JSON regions and commands
    w.put_status({"phase": "running", "run": 1})
    assert r.get_json("status")[1] == {"phase": "running", "run": 1}
    seq = r.send_command({"cmd": "hold"})
    assert w.read_command() == (seq, {"cmd": "hold", "seq": seq})
    assert r.writer_pid == os.getpid() and r.heartbeat_age_s() < 5 and not r.closed
    w.close()
    assert r.closed
    r.close()


def test_a_copy_taken_while_the_history_wraps_drops_the_rows_overwritten(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """rows_since copies outside the reader's lock (a whole run's copy must not hold up every
    frame). Another thread's pull that wraps the history over the oldest rows being copied: those
    rows are dropped, what is returned is the generator's."""
    import rig.console.ring as ring_module

    w = RingWriter(tmp_path / "r.ring", sample_bytes=3 * 8 * 30 * 8)  # 8 slots of 30 rows
    r = RingReader(w.path, mirror_bytes=3 * 4 * 100)  # a history of 100 rows
    w.begin_run(_meta(), 3, np.dtype(np.float64), 30)
    ramp = np.arange(400, dtype=float)

    def block(k: int) -> np.ndarray:
        return np.vstack([ramp[k : k + 30], -ramp[k : k + 30], ramp[k : k + 30] * 2])

    for k in range(0, 120, 30):
        w.write(k, block(k))
    r.pull()  # rows 20..119 in the history
    copy = ring_module._oldest_first

    def copy_while_two_blocks_arrive(buf: np.ndarray, start: int, stop: int) -> np.ndarray:
        half = copy(buf, start, start + (stop - start) // 2)
        for k in (120, 150):  # meanwhile: rows 120..179 overwrite rows 20..79
            w.write(k, block(k))
        r.pull()
        return np.concatenate([half, copy(buf, start + len(half), stop)])

    monkeypatch.setattr(ring_module, "_oldest_first", copy_while_two_blocks_arrive)
    gen, first, offset, rows = r.rows_since(-1, 0)
    assert gen == 1 and offset == 0 and first == 80 and len(rows) == 40  # 80..119 intact
    assert np.array_equal(rows, np.c_[ramp[80:120], -ramp[80:120], 2 * ramp[80:120]])
    monkeypatch.undo()
    _, first, _, rows = r.rows_since(1, 0)  # the next look: the history as it now stands
    assert first == 80 and np.array_equal(rows[:, 0], ramp[80:180])
    r.close()
    w.close(unlink=True)


def test_ring_keeps_volts_as_float32_and_codes_as_int16(tmp_path: Path) -> None:
    # The reader's history: half the memory of float64; the page rounds to 0.1 N.
    w = RingWriter(tmp_path / "r.ring", sample_bytes=3 * 8 * 60 * 2)
    r = RingReader(w.path, mirror_bytes=3 * 4 * 64)
    w.begin_run(_meta(), 3, np.dtype(np.float64), 60)
    t = np.arange(100) / RATE_HZ
    volts = np.vstack([np.sin(2 * np.pi * 7 * t), 3.3 * np.cos(t), np.full(100, -9.87654321)])
    w.write(0, volts[:, :60])
    w.write(60, volts[:, 60:])  # wraps at 64 rows
    _, first, _, rows = r.rows_since(-1, 0)
    assert first == 36 and rows.dtype == np.float32
    assert np.array_equal(rows, volts[:, 36:].T.astype(np.float32))
    assert np.abs(rows - volts[:, 36:].T).max() < 1e-6  # volts to a microvolt
    w.begin_run(_meta(), 2, np.dtype(np.int16), 3)
    codes = np.array([[-32768, 0, 32767], [1, -1, 12345]], np.int16)
    w.write(0, codes)
    _, _, _, rows = r.rows_since(-1, 0)
    assert rows.dtype == np.int16 and np.array_equal(rows, codes.T)
    w.close()
    r.close()


def test_not_a_ring_is_one_clear_error(tmp_path: Path) -> None:
    p = tmp_path / "x.ring"
    p.write_bytes(b"\0" * 10)
    with pytest.raises(RingError, match="not a cutlab live ring"):
        RingReader(p)
    with pytest.raises(RingError, match="cannot open"):
        RingReader(tmp_path / "missing.ring")


ORIGIN = {"origin": "http://127.0.0.1"}  # the page's own (the Host of WS)
WS = "ws://127.0.0.1/ws"


def _client(app: object) -> object:
    """Starlette's TestClient as the page is: on 127.0.0.1, with the session's token."""
    from starlette.testclient import TestClient

    return TestClient(app, base_url="http://127.0.0.1",
                      headers={"authorization": f"Bearer {app.state.token}"})  # fmt: skip


def _live_folder(tmp_path: Path) -> tuple[Path, RingWriter]:
    folder = tmp_path / "camp"
    (folder / "runs").mkdir(parents=True)
    w = RingWriter(tmp_path / "live.ring")
    (folder / "live.json").write_text(json.dumps({"ring": str(w.path), "pid": os.getpid()}))
    return folder, w


def test_websocket_frames_carry_min_max_per_pixel_and_the_status(tmp_path: Path) -> None:
    from rig.console.server import make_app

    folder, w = _live_folder(tmp_path)
    w.begin_run(_meta(zero=[0.5, 0.0, 0.0]), 3, np.dtype(np.float64))
    n = 2000  # 2 s at 1 kHz
    t = np.arange(n) / RATE_HZ
    fx = 0.5 + np.sin(2 * np.pi * 3.0 * t)  # volts; zero 0.5 V, 100 N/V
    w.write(0, np.vstack([fx, np.zeros(n), np.full(n, 0.25)]))
    w.put_status({"phase": "running", "run": 1, "runs": 2, "executing_block": 7})
    with _client(make_app(folder)) as client:
        assert client.get("/api/health").json()["live"] is True
        page = client.get("/")
        assert page.status_code == 200 and 'data-testid="frame-count"' in page.text
        assert client.get("/static/uPlot.iife.min.js").status_code == 200
        with client.websocket_connect(WS, headers=ORIGIN) as ws:
            ws.send_json({"type": "hello", "px": 100, "window_s": 2.0})  # 20 samples a bin
            msgs = [ws.receive_json() for _ in range(4)]
            # the frame after the hello starts over at its resolution
            bins = [m["bins"] for m in msgs if m.get("reset") and "bins" in m][-1]
            status = next(m["status"] for m in msgs if "status" in m)
            assert status["executing_block"] == 7
            ws.send_json({"type": "cmd", "cmd": "hold"})
            reply = next(m for m in (ws.receive_json() for _ in range(5)) if m["type"] == "cmd")
    assert reply["ok"] and w.read_command()[1]["cmd"] == "hold"
    # Independent reference: 100 bins of 20 samples each over the 2 s, forces in N.
    ref = 100.0 * (fx - 0.5).reshape(100, 20)
    k = len(bins["t"]) - 1  # the last bin may still be growing: compare the complete ones
    assert np.allclose(bins["t"][:k], 5.0 + np.arange(k) * 0.02)
    assert np.allclose(bins["max"][0][:k], ref.max(axis=1)[:k], atol=0.06)
    assert np.allclose(bins["min"][0][:k], ref.min(axis=1)[:k], atol=0.06)
    assert np.allclose(bins["max"][2][:k], 25.0)
    w.close(unlink=True)


def test_a_command_is_refused_when_no_campaign_runs(tmp_path: Path) -> None:
    from rig.console.server import make_app

    folder, w = _live_folder(tmp_path)
    w.close()  # the campaign ended
    with _client(make_app(folder)) as client, client.websocket_connect(WS, headers=ORIGIN) as ws:
        ws.send_json({"type": "cmd", "cmd": "abort"})
        reply = next(m for m in (ws.receive_json() for _ in range(5)) if m["type"] == "cmd")
        assert not reply["ok"] and "no campaign" in reply["message"]
    # a page elsewhere cannot reach the feed hold
    with _client(make_app(folder)) as client:
        with pytest.raises(Exception):  # noqa: B017 - starlette raises its disconnect
            with client.websocket_connect(WS, headers={"origin": "http://evil.example"}) as ws:
                ws.receive_json()


def _run_file(path: Path) -> tuple[np.ndarray, float]:
    """A run file of one channel: a ramp of 3000 samples at 1 kHz, three blocks."""
    from rig.log import RunWriter

    info = DaqInfo("test", ("t/ai0",), ("Fx",), RATE_HZ, rf.SAMPLE_FORMAT_VOLTS, 10.0, 500)
    data = np.arange(3000, dtype=float)[None, :] / 1000.0
    t0 = 2.0
    with RunWriter(path, info, clock=lambda: t0) as w:
        w.on_start(info, t0)
        for k in range(0, 3000, 500):
            w.put_block(k, data[:, k : k + 500])
        w.set_program("G0 X0\nG1 X10 F100\nM30\n", "p.nc")
        w.append_blocks([0, 1, 2], [1, 2, 3], ["G0 X0", "G1 X10 F100", "M30"],
                        [2.0, 2.0, 2.0], exec_s=[2.0, 2.5, 4.0])  # fmt: skip
    return data[0], t0


def test_run_browser_lists_runs_and_gives_traces_by_block(tmp_path: Path) -> None:
    from rig.console.server import make_app

    folder = tmp_path / "camp"
    (folder / "runs").mkdir(parents=True)
    volts, t0 = _run_file(folder / "runs" / "000-a.h5")
    with _client(make_app(folder)) as client:
        runs = client.get("/api/runs").json()["runs"]
        assert runs == [{"file": "000-a.h5", "status": "success", "reason": ""}]
        info = client.get("/api/run", params={"file": "000-a.h5"}).json()
        spans = [(b["block"], b["t0"], b["t1"]) for b in info["blocks"]]
        assert spans == [(0, 2.0, 2.5), (1, 2.5, 4.0), (2, 4.0, 5.0)]
        assert info["program"] == ["G0 X0", "G1 X10 F100", "M30"]
        # its toolpath: G1 X10 from its start at 2.5 s, done when the next block began at 4.0 s
        # (6 s at F100, squeezed into the 1.5 s it took), the tool at X0 before; volts: no force
        path = info["path"]
        assert [s[:6] for s in path["toolpath"] if s[1] == 1] == [[1, 1, 0.0, 0.0, 10.0, 0.0]]
        moving = [p for p in path["trail"] if p[0] >= 2.5]
        assert moving[0][:2] == [2.5, 0.0] and moving[-1][:2] == [4.0, 10.0]
        assert all(abs(p[1] - 10 * (p[0] - 2.5) / 1.5) < 1e-3 for p in moving)
        assert all(p[1] == 0.0 for p in path["trail"] if p[0] < 2.5)
        assert all(p[5] is None for p in path["trail"]) and "estimated" in path["source"]
        # block 1 (2.5 .. 4.0 s) in 15 bins of 100 samples: volts ramp 0.5 .. 2.0 V
        tr = client.get("/api/trace", params={"file": "000-a.h5", "t0": 2.5, "t1": 4.0,
                                              "px": 15}).json()  # fmt: skip
        assert tr["unit"] == "V"
        ref = volts[500:2000].reshape(15, 100)
        assert np.allclose(tr["min"][0], ref.min(axis=1), atol=0.011)
        assert np.allclose(tr["max"][0], ref.max(axis=1), atol=0.011)
        bad = client.get("/api/run", params={"file": "../../etc/passwd"})
        assert bad.status_code == 404 and "no run file" in bad.json()["error"]
    # a single run file is a target too
    with _client(make_app(folder / "runs" / "000-a.h5")) as client:
        assert [r["file"] for r in client.get("/api/runs").json()["runs"]] == ["000-a.h5"]


def test_console_command_bad_target_is_one_line(tmp_path: Path) -> None:
    p = subprocess.run(
        [sys.executable, "-c", "from rig.cli.console import register; import argparse;"
         "from rig.cli import main; import sys; sys.exit(main(sys.argv[1:]))",
         "console", str(tmp_path / "nothing"), "--port", "8765"],
        cwd=ROOT, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert p.stderr.startswith("cutlab: error: console:") and "campaign folder" in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1


def test_readouts_are_per_revolution_mean_peak_rms(tmp_path: Path) -> None:
    from rig.console.server import make_app

    folder, w = _live_folder(tmp_path)
    meta = _meta(zero=[0.0, 0.0, 0.0]) | {"spindle_rpm": 600.0}  # 100 samples a revolution
    w.begin_run(meta, 3, np.dtype(np.float64))
    n = 1050  # 10 whole revolutions and a part
    k = np.arange(n)
    fx = 0.5 + np.sin(2 * np.pi * k / 100.0)  # once a revolution; 100 N/V
    w.write(0, np.vstack([fx, np.full(n, -0.2), np.zeros(n)]))
    with _client(make_app(folder)) as client, client.websocket_connect(WS, headers=ORIGIN) as ws:
        r = next(m["readouts"] for m in (ws.receive_json() for _ in range(30)) if "readouts" in m)
    w.close(unlink=True)
    # Independent reference, by hand: the last whole revolution is the 10th (k = 9, samples
    # 900..999); 50 + 100 sin: mean 50 N, peak 150 N (sample 925), RMS sqrt(50^2 + 100^2 / 2).
    assert r["rev"] == 9 and r["rpm"] == 600.0 and r["t_s"] == pytest.approx(5.0 + 0.9)
    assert r["mean"] == pytest.approx([50.0, -20.0, 0.0], abs=0.01)
    assert r["peak"] == pytest.approx([150.0, -20.0, 0.0], abs=0.01)
    assert r["rms"] == pytest.approx([(50.0**2 + 100.0**2 / 2) ** 0.5, 20.0, 0.0], abs=0.01)


def test_the_drip_feed_dro_is_estimated_from_the_program() -> None:
    from rig.console.live import ProgramPath

    text = "G21 G90\nS1000 M3\nG0 X0 Y0 Z5\nG1 Z-1 F100\nG1 X10 F600\nG0 Z5\n"
    path = ProgramPath(text, None)
    # By hand: block 4 (line 5) goes 10 mm at 600 mm/min, 1 s; block 3 goes 6 mm down at
    # 100 mm/min, 3.6 s.
    half = path.estimate(4, 0.5)
    assert half["pos_mm"] == pytest.approx([5.0, 0.0, -1.0])
    assert half["feed_mm_min"] == 600.0 and half["spindle_rpm"] == 1000.0
    assert half["block_end_mm"] == pytest.approx([10.0, 0.0, -1.0])
    assert path.estimate(4, 9.0)["pos_mm"] == pytest.approx([10.0, 0.0, -1.0])  # then it waits
    assert path.estimate(3, 1.8)["pos_mm"] == pytest.approx([0.0, 0.0, 2.0])
    assert path.estimate(0, 0.0) is None  # modes only: the page keeps the last estimate
    segs = path.toolpath()
    assert [s[0] for s in segs] == [2, 3, 4, 5] and segs[2][2:6] == [0.0, 0.0, 10.0, 0.0]
    # Z last (the 3-D view): the plunge from 5 to -1 mm, the cut at -1 mm
    assert [s[6:] for s in segs] == [[0.0, 5.0], [5.0, -1.0], [-1.0, -1.0], [-1.0, 5.0]]


def test_grbl_dro_is_its_status_report() -> None:
    from types import SimpleNamespace

    from rig.console.live import machine_report
    from rig.dnc.grbl import parse_status

    st = parse_status("<Hold:0|MPos:12.500,-3.250,-1.000|FS:450,12000|Ov:110,50,95>")
    session = SimpleNamespace(streamer=SimpleNamespace(last_status=st, _wco=(2.0, 0.0, 0.0)))
    m = machine_report(session)
    assert m["state"] == "Hold:0" and m["source"] == "GRBL status" and not m["estimated"]
    assert m["pos_mm"] == [10.5, -3.25, -1.0]  # work position: MPos less the offset
    assert (m["feed_mm_min"], m["spindle_rpm"]) == (450, 12000)
    assert m["overrides_pct"] == {"feed": 110, "rapid": 50, "spindle": 95}


def test_the_live_run_zooms_to_raw_samples_and_scrolls_back_binned(tmp_path: Path) -> None:
    from rig.console.server import make_app

    folder, w = _live_folder(tmp_path)
    w.begin_run(_meta(zero=[0.5, 0.0, 0.0]), 3, np.dtype(np.float64))
    n = 2000
    ramp = np.arange(n) / 1000.0  # volts
    for k in range(0, n, 250):
        w.write(k, np.vstack([ramp[k : k + 250], np.zeros(250), np.ones(250)]))
    with _client(make_app(folder)) as client:
        whole = client.get("/api/trace", params={"live": 1, "px": 100}).json()
        zoom = client.get("/api/trace", params={"live": 1, "t0": 5.5, "t1": 5.6, "px": 100})
    w.close(unlink=True)
    # the whole run: 100 bins of 20 samples (run clock from t0 = 5 s), min and max by hand
    assert not whole["raw"] and whole["n"] == n and len(whole["t"]) == 100
    assert np.allclose(whole["min"][0], 100.0 * (ramp[::20] - 0.5), atol=0.01)
    assert np.allclose(whole["max"][0], 100.0 * (ramp[19::20] - 0.5), atol=0.01)
    # zoomed to 0.1 s: the samples themselves, 5.500 .. 5.600 s
    z = zoom.json()
    assert z["raw"] and z["n"] == 101 and z["t"][0] == pytest.approx(5.5)
    assert np.allclose(z["min"][0], 100.0 * (ramp[500:601] - 0.5), atol=1e-3)
    assert np.allclose(z["max"][2], 100.0)


def test_history_lists_the_campaigns_from_the_catalogue_or_the_folders(tmp_path: Path) -> None:
    from analysis.catalog import update_index
    from rig.console.server import make_app

    lab = tmp_path / "lab"
    for name, statuses in (("camp", ["success", "abort"]), ("other", ["success"])):
        (lab / name / "runs").mkdir(parents=True)
        runs = {f"r{i}": {"status": st, "file": f"runs/{i:03d}.h5"} for i, st in
                enumerate(statuses)}  # fmt: skip
        (lab / name / "campaign.json").write_text(json.dumps({"runs": runs}))
    with _client(make_app(lab / "camp")) as client:
        h = client.get("/api/history").json()
    assert "campaign folders" in h["source"]
    seen = [(c["campaign"], c["runs"], c["statuses"], c["this"]) for c in h["campaigns"]]
    assert seen == [("camp", 2, {"success": 1, "abort": 1}, True),
                    ("other", 1, {"success": 1}, False)]  # fmt: skip
    # with a run catalogue of the lab folder: its rows, by campaign
    _run_file(lab / "camp" / "runs" / "000-a.h5")
    _run_file(lab / "other" / "runs" / "000-b.h5")
    update_index([lab])
    with _client(make_app(lab / "camp")) as client:
        h = client.get("/api/history").json()
    assert "run catalogue" in h["source"] and sum(c["runs"] for c in h["campaigns"]) == 2


def test_a_console_left_to_browse_gives_its_port_to_the_next_live_campaign(tmp_path: Path) -> None:
    import socket
    import time

    from rig.console import live

    pytest.importorskip("uvicorn")
    folder = tmp_path / "camp"
    (folder / "runs").mkdir(parents=True)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    proc = live.start_server(folder, port, "127.0.0.1", "tok")
    try:
        live.leave_server(proc, live.url_of("127.0.0.1", port, "tok"))  # the campaign ended
        os.kill(proc.pid, 0)  # it stays to browse (not waited for: its status is not kept)
        with pytest.raises(Exception, match="cannot listen"):
            live.check_port("127.0.0.1", port)
        live.end_lingering("127.0.0.1", port)  # a new live campaign on that port
        t_end = time.monotonic() + 10
        while True:  # the port is free once the old server's socket is gone
            try:
                live.check_port("127.0.0.1", port)
                break
            except Exception:
                assert time.monotonic() < t_end, "the port was not given back"
                time.sleep(0.1)
    finally:
        proc.returncode = None
        if proc.poll() is None:
            proc.kill()
        proc.wait(timeout=10)


def test_the_status_carries_every_event_as_json_encodes_it(tmp_path: Path) -> None:
    """The events are encoded once per new event and spliced into the status (not 25 times a
    second): the page gets the same object (and the same bytes) as encoding them in place, up to
    MAX_EVENTS, with messages that hold the splice's own marker."""
    from rig.campaign import load_campaign
    from rig.console.live import MAX_EVENTS, LiveCampaign

    live = LiveCampaign(load_campaign("facemill-ploughing"), tmp_path)  # its thread publishes
    reader = RingReader(live.ring.path)
    try:
        for i in range(MAX_EVENTS + 30):
            live.note("gap", f'{i} samples missing "events":null \u00e9', 0.5 * i)
            if i % 23 and i != MAX_EVENTS + 29:
                continue
            expected = json.loads(json.dumps(list(live.events)))
            t_end = time.monotonic() + 10
            while True:  # the next tick (25 a second) publishes them
                seq, status = reader.get_json("status")
                raw = bytes(reader._region("status")[: reader.h[19]])
                if reader.seq("status") == seq and status and status["events"] == expected:
                    break
                assert time.monotonic() < t_end, "the events never reached the status"
                time.sleep(0.01)
            assert len(expected) == min(i + 1, MAX_EVENTS)
            assert raw == json.dumps(status, separators=(",", ":")).encode()
    finally:
        reader.close()
        live.close()
        live.ring.path.unlink(missing_ok=True)
