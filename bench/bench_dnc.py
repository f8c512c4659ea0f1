"""DNC streaming figures over real pseudo-terminals to the simulated controllers.

Prints, for Fanuc drip feed (XON/XOFF in the streamer) and GRBL (character counting):

1. starvation at 100 blocks/s: 1 mm segments at 6000 mm/min, 115200 baud emulated by the
   controller, real time (speed 1): the fraction of time the controller waited for a block after
   the first one (target 0), achieved bytes/s against the line rate and against what execution
   needs;
2. line-limited throughput: 0.1 mm segments (1000 blocks/s, more than the line carries): bytes/s
   against the line rate;
3. byte-exact delivery of a 12,000-block program (faster than real time): SHA-256 of what the
   controller received against what was meant, and how often flow control stopped the sender
   (Fanuc DC3 count, GRBL planner-full waits), largest number of characters that arrived after a
   DC3 (a real Fanuc tolerates about 10; the simulated one alarms past 1024).

Run: ``.venv/bin/python bench/bench_dnc.py [--blocks 1000] [--exact-blocks 12000] [--json]``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time

from analysis.config import SerialConfig
from planning.nc.grbl import grbl_send_text
from rig.dnc import FanucStreamer, GrblStreamer, MemorySink, program_from_text
from rig.dnc.grbl import HANDSHAKE
from rig.sim import SimClock, SimFanuc, SimGrbl

BAUD = 115200


FEED = 6000.0


def program(n: int, step_mm: float, feed_mm_min: float = FEED, grbl: bool = False):
    # segments of exactly step_mm: 1 mm at 6000 mm/min is 10 ms, i.e. 100 blocks/s
    head = ["%", "G21 G90 G17 G54", "S3000 M3", "G0 X0 Y0 Z5", "G0 Z0.1"]
    body = [f"G1 X{(i + 1) * step_mm:.3f} F{feed_mm_min:g}" for i in range(n)]
    return program_from_text("\n".join(head + body + ["G0 Z50", "M5", "M30", "%"]) + "\n", "b.nc")


def sent_texts(prog, protocol: str) -> list[str]:
    """The lines as the streamer sends them (GRBL: stripped of comments and spaces)."""
    if protocol == "grbl":
        return [t for t in (grbl_send_text(b.text) for b in prog.blocks) if t]
    return [b.text for b in prog.blocks]


def expected_bytes(prog, protocol: str, leader: int) -> bytes:
    body = b"".join(t.encode() + b"\n" for t in sent_texts(prog, protocol))
    if protocol == "grbl":
        return HANDSHAKE + body
    lead = b"\0" * leader
    return lead + b"%\n" + body + b"%" + lead


def run(protocol: str, prog, speed: float) -> dict:
    clock = SimClock(speed)
    if protocol == "fanuc":
        ctl = SimFanuc(clock=clock, baudrate=BAUD)
        line = BAUD / 11
        cfg = SerialConfig(port="x", baudrate=BAUD, leader_nuls=10, timeout_s=10)
    else:
        ctl = SimGrbl(clock=clock, baudrate=BAUD)
        line = BAUD / 10
        cfg = SerialConfig(port="x", baudrate=BAUD, bytesize=8, parity="N", stopbits=1,
                           flow_control="none", timeout_s=10)  # fmt: skip
    done = __import__("threading").Event()
    ctl.add_listener(on_event=lambda ev: ev.kind == "program_end" and done.set())
    with ctl:
        cfg = cfg.model_copy(update={"port": ctl.path})
        sink = MemorySink()
        kw = dict(clock=clock.now, pace_bytes_per_s=line * speed, sink=sink)
        st = FanucStreamer(cfg, **kw) if protocol == "fanuc" else GrblStreamer(cfg, **kw)
        t0 = time.perf_counter()
        res = st.send(prog)
        if protocol == "fanuc":
            done.wait(600)
        wall = time.perf_counter() - t0
    # the body: the feed moves after the header
    body = [b for b in ctl.executed if b.text.endswith(f"F{FEED:g}")]
    exec_s = sum(b.t_end_s - b.t_start_s for b in body)
    n_bytes = sum(len(b.text) + 1 for b in body)
    rows = [r for r in sink.rows if r.text.endswith(f"F{FEED:g}")]
    span_s = rows[-1].send_time_s - rows[0].send_time_s  # simulated s
    sent_rate = sum(r.n_bytes for r in rows[:-1]) / span_s
    want = expected_bytes(prog, protocol, 10)
    return {
        "protocol": protocol,
        "blocks": len(prog),
        "speed": speed,
        "wall_s": round(wall, 2),
        "starved_fraction": round(ctl.starved_fraction, 5),
        "starved_s": round(ctl.starved_s, 4),
        "executing_s": round(exec_s, 2),
        "grbl_status_starved_fraction": res.starved_fraction,
        "bytes_per_s": round(sent_rate, 1),  # while sending the body, per simulated second
        "line_bytes_per_s": round(line, 1),
        "of_line_rate": round(sent_rate / line, 3),
        "needed_bytes_per_s": round(n_bytes / max(exec_s, 1e-9), 1),
        "stream_s": round(res.seconds, 2),
        "sha256_match": hashlib.sha256(bytes(ctl.received)).digest()
        == hashlib.sha256(want).digest(),
        "bytes_received": len(ctl.received),
        "xoff_count": getattr(ctl, "xoff_count", None),
        "max_chars_after_xoff": getattr(ctl, "max_after_xoff", None),
        "planner_full_waits": getattr(ctl, "planner_waits", None),
        "overruns": ctl.overruns,
        "executed_all": ctl.executed_texts() == sent_texts(prog, protocol),
    }


def run_subprocess(protocol: str, prog) -> dict:
    """The controller in its own process (``cutlab dnc sim-controller``), real time: the figures
    without the streamer and the controller sharing one interpreter lock."""
    import select
    import signal
    import subprocess

    import serial

    machine = "ace-h63" if protocol == "fanuc" else "lab-grbl"
    cmd = [sys.executable, "-m", "rig.cli", "dnc", "sim-controller", "--protocol", protocol,
           "--machine", machine, "--baud", str(BAUD), "--json"]  # fmt: skip
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        if not select.select([proc.stdout], [], [], 30)[0]:
            raise RuntimeError("sim-controller printed no path")
        path = proc.stdout.readline().strip()
        from analysis.config import load_machine

        cfg = load_machine(machine).serial.model_copy(
            update={"port": path, "baudrate": BAUD, "timeout_s": 10}
        )
        sink = MemorySink()
        st = FanucStreamer(cfg, sink=sink) if protocol == "fanuc" else GrblStreamer(cfg, sink=sink)
        res = st.send(prog)  # paces at the line rate itself (the port is a pty)
        if protocol == "fanuc":  # back in its waiting state, the control repeats DC1: done
            with serial.serial_for_url(path, baudrate=BAUD, timeout=60) as ser:
                ser.read_until(b"\x11")
    finally:
        proc.send_signal(signal.SIGTERM)
        out, _ = proc.communicate(timeout=60)
    sim = json.loads(out)
    rows = [r for r in sink.rows if r.text.endswith(f"F{FEED:g}")]
    span_s = rows[-1].send_time_s - rows[0].send_time_s
    rate = sum(r.n_bytes for r in rows[:-1]) / span_s
    line = BAUD / (11 if protocol == "fanuc" else 10)
    want = expected_bytes(prog, protocol, cfg.leader_nuls)
    return {
        "protocol": protocol,
        "blocks": len(prog),
        "starved_fraction": round(sim["starved_fraction"], 5),
        "grbl_status_starved_fraction": res.starved_fraction,
        "bytes_per_s": round(rate, 1),
        "line_bytes_per_s": round(line, 1),
        "of_line_rate": round(rate / line, 3),
        "sha256_match": sim["sha256"] == hashlib.sha256(want).hexdigest(),
        "xoff_count": sim.get("xoff_count"),
        "max_chars_after_xoff": sim.get("max_chars_after_xoff"),
        "planner_full_waits": sim.get("planner_full_waits"),
        "overruns": sim["overruns"],
        "executed_all": sim["blocks_executed"] == len(sent_texts(prog, protocol)),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--blocks", type=int, default=1000, help="blocks of the real-time runs")
    ap.add_argument("--exact-blocks", type=int, default=12000, help="blocks of the exact runs")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    out: dict[str, list[dict]] = {
        "starvation_100_blocks_s": [],
        "starvation_100_blocks_s_controller_in_own_process": [],
        "line_limited": [],
        "exact": [],
    }
    for proto in ("fanuc", "grbl"):
        g = proto == "grbl"
        print(f"[{proto}] 100 blocks/s, real time ...", file=sys.stderr, flush=True)
        out["starvation_100_blocks_s"].append(run(proto, program(a.blocks, 1.0, grbl=g), 1.0))
        print(f"[{proto}] 100 blocks/s, controller in its own process ...", file=sys.stderr)
        out["starvation_100_blocks_s_controller_in_own_process"].append(
            run_subprocess(proto, program(a.blocks, 1.0, grbl=g))
        )
        print(f"[{proto}] line-limited, real time ...", file=sys.stderr, flush=True)
        out["line_limited"].append(run(proto, program(a.blocks, 0.1, grbl=g), 1.0))
        print(f"[{proto}] {a.exact_blocks} blocks byte-exact ...", file=sys.stderr, flush=True)
        speed = 4.0 if proto == "fanuc" else 10.0
        out["exact"].append(run(proto, program(a.exact_blocks, 1.0, grbl=g), speed))
    if a.json:
        json.dump(out, sys.stdout, indent=2)
        print()
        return 0
    cols = ("protocol", "blocks", "speed", "wall_s", "starved_fraction", "bytes_per_s",
            "line_bytes_per_s", "of_line_rate", "needed_bytes_per_s", "sha256_match",
            "xoff_count", "max_chars_after_xoff", "planner_full_waits", "overruns",
            "executed_all")  # fmt: skip
    for name, rows in out.items():
        print(f"\n== {name} ==")
        for r in rows:
            print("  " + ", ".join(f"{c}={r[c]}" for c in cols if c in r))
    return 0


if __name__ == "__main__":
    sys.exit(main())
