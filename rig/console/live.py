"""The campaign side of the live console: a tap beside the logger, the state the page shows, and
the page's hold / resume / abort.

It fits in through the runner's existing entry points (:func:`rig.campaign.run_campaign`'s
``session_factory`` and ``stop``), so a campaign runs the same with or without it::

    with live_console(campaign, out_root, port=8765) as live:
        result = run_campaign(campaign, out_root=out_root, **live.run_kwargs())

- Samples: each rig session's DAQ sink is teed: the run writer gets every block first, its
  queue buffers the ring's slots (:mod:`rig.console.ring`: its one copy is the page's too), then
  the live side (gaps, the logger's health); an error there is dropped, never raised into the
  acquisition thread.
- State, about 25 times a second: the machine as the controller reports it (GRBL status reports;
  the simulated control's panel; a drip feed reports nothing), the streamer's sent /
  acknowledged / executing blocks, the executed blocks' spans, run i of N, elapsed and remaining
  time, events.
- Commands from the page: hold (feed hold), resume (cycle start), abort (the runner's stop: feed
  hold, stop, the run closed ``abort``, the campaign ended). The page shows the state read back.
"""

from __future__ import annotations

import bisect
import contextlib
import json
import math
import os
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from analysis.runs import file as rf
from rig.campaign.run import StopRequest
from rig.campaign.runner import campaign_folder, default_session_factory, plan_campaign
from rig.console.chatter import stability_case
from rig.console.common import (  # noqa: F401 - re-exported: the server and the CLI use them
    LINGER_S,
    LIVE_FILE,
    TICK_S,
    TOKEN_ENV,
    WILDCARD_BINDS,
    pid_alive,
    url_of,
)
from rig.console.health import LoggerHealth
from rig.console.process import (  # noqa: F401 - re-exported: rig.cli.console, bench
    check_console_extra,
    check_port,
    end_lingering,
    leave_server,
    remove_stale,
    start_server,
    stop_server,
)
from rig.console.program_path import ProgramPath, _jsonable
from rig.console.results import RunKwargs
from rig.console.ring import RingWriter
from rig.console.session import LiveSink, _LiveSession, _Tee, machine_report  # noqa: F401
from rig.daq import Calibration, DaqEvent, DaqInfo

if TYPE_CHECKING:
    from rig.campaign.config import Campaign
    from rig.campaign.runner import SessionFactory
    from rig.dnc import Program

MAX_EVENTS = 200
BANDS_S = 60.0  # the executed blocks sent to the page: those of the longest window it shows
#: DAQ and runner event kinds the page lists (the others are bookkeeping)
SHOWN_EVENTS = {rf.EV_OVERFLOW, rf.EV_FAULT, rf.EV_GAP, rf.EV_QUEUE_FULL, rf.EV_INTERLOCK,
                rf.EV_PAUSE, rf.EV_RESUME, "saturation", "chatter", "alarm", "abort"}  # fmt: skip


class LiveCampaign:
    """The live side of one campaign (see the module docstring).

    ``folder``: the campaign's folder (``live.json`` there points servers at the ring).
    """

    def __init__(
        self, campaign: Campaign, folder: Path, ring_path: str | Path | None = None
    ) -> None:
        self.campaign = campaign
        self.folder = Path(folder)
        plans = plan_campaign(campaign)
        self.n_runs = len(plans)
        sim = campaign.spec.campaign.rig == "sim"
        self.speed = float(campaign.spec.sim.speed) if sim and campaign.spec.sim.speed else 1.0
        self.expected_wall_s = [p.expected_s / self.speed for p in plans]
        self.run_names = [p.test.name for p in plans]
        self.rpms = [float(p.test.spindle_rpm) for p in plans]
        self.tests = [p.test for p in plans]
        self.cal = Calibration.from_dynamometer(campaign.rig.dynamometer)
        self.ring = RingWriter(ring_path)
        self.stop = StopRequest()
        self.events: deque[dict[str, Any]] = deque(maxlen=MAX_EVENTS)
        self._events_n = 0  # events noted so far: the key of the events' JSON below
        self._events_json = (0, b"[]")
        self.phase = "starting"
        self.message = ""
        self._lock = threading.Lock()
        self._session: _LiveSession | None = None
        self._run_k = -1
        self._run_wall0 = math.nan
        self._wall0 = time.monotonic()
        self._info: DaqInfo | None = None
        self._health: LoggerHealth | None = None
        self._t0_s = math.nan
        self._expect = 0
        self._meta: dict[str, Any] = {}
        self._bands: list[list[Any]] = []
        self._line_of: dict[int, int] = {}  # block -> program line, set once per program
        self._executing = -1
        self._exec_t0 = math.nan  # run clock s the executing block started
        self._path: ProgramPath | None = None
        self._dro: dict[str, Any] = {}  # the last estimate (a block without motion keeps it)
        self._overrides: dict[str, int] | None = None
        self._held = False  # hold sent and no resume since (for a control that reports no state)
        self._fault_seen: str | None = None
        self._cmd_done = self.ring.read_command()[0]
        self._last_cmd: dict[str, Any] = {}
        self.tap_errors = 0
        self._closed = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="console-live", daemon=True)
        self._thread.start()

    # -- the runner's entry points -------------------------------------------------------------
    def run_kwargs(self) -> RunKwargs:
        """What :func:`run_campaign` takes to run with the console."""
        return {"session_factory": self.session_factory(), "stop": self.stop}

    def session_factory(self, inner: SessionFactory | None = None) -> SessionFactory:
        make = inner or default_session_factory(self.campaign)

        def factory(campaign: Campaign, plan: Any, k: int) -> _LiveSession:
            session = _LiveSession(make(campaign, plan, k), self)
            with self._lock:
                self._session, self._run_k = session, k
                self._run_wall0 = time.monotonic()
                self._bands, self._fault_seen, self._executing = [], None, -1
                self._line_of, self._path, self._dro, self._held = {}, None, {}, False
                self._exec_t0 = math.nan
                self.phase = "running"
            return session

        return factory

    # -- the tap (acquisition thread: quick, and never raises) ---------------------------------
    def guard(self, fn: Callable[..., None], *args: object) -> None:
        try:
            fn(*args)
        except Exception:  # noqa: BLE001 - the live view must never endanger the recording
            self.tap_errors += 1

    def on_start(self, info: DaqInfo, t0_s: float) -> None:
        self._info, self._t0_s, self._expect = info, float(t0_s), 0
        self._health = LoggerHealth(info.rate_hz, t0_s)
        self._meta = self._run_meta(info, t0_s)
        self.ring.begin_run(self._meta, info.n_channels, info.dtype, info.block_samples)

    def share_with(self, sink: object) -> None:
        """The run writer behind the DAQ's ``sink`` (a tap's ``writer``, a tee's ``sink``)
        takes its queue buffers from the ring: its one copy of each block is the page's too
        (after :meth:`on_start`; a writer that cannot leaves the ring copying blocks itself)."""
        for _ in range(5):
            share = getattr(sink, "share_buffers", None)
            if share is not None:
                share(self.ring)
                return
            sink = getattr(sink, "writer", None) or getattr(sink, "sink", None)

    def on_block(self, first_sample: int, data: np.ndarray) -> None:
        if first_sample > self._expect and self._info is not None:
            lost = first_sample - self._expect
            self.note(rf.EV_GAP, f"{lost} samples missing",
                      self._t0_s + self._expect / self._info.rate_hz)  # fmt: skip
        self._expect = first_sample + int(data.shape[1])
        self.ring.write(first_sample, data)
        s, health = self._session, self._health
        if s is not None and health is not None:
            health.on_block(data.shape[1], s.clock())

    def on_event(self, event: DaqEvent) -> None:
        if event.kind in SHOWN_EVENTS:
            t = event.time_s
            if not math.isfinite(t) and event.sample >= 0 and self._info is not None:
                t = self._t0_s + event.sample / self._info.rate_hz
            self.note(event.kind, event.message, t)

    def note(self, kind: str, message: str, time_s: float | None = None) -> None:
        if time_s is None and self._session is not None:
            time_s = self._session.clock()
        self.events.append({"run": self._run_k + 1, "kind": kind, "message": message[:300],
                            "t_s": _jsonable(time_s), "wall": time.time()})  # fmt: skip
        self._events_n += 1

    # -- run info ------------------------------------------------------------------------------
    def _run_meta(self, info: DaqInfo, t0_s: float) -> dict[str, Any]:
        k = self._run_k
        return {
            "campaign": self.campaign.name,
            "run": k + 1,
            "runs": self.n_runs,
            "name": self.run_names[k] if 0 <= k < self.n_runs else "",
            "channels": list(info.channel_names),
            "rate_hz": info.rate_hz,
            "t0_s": t0_s,
            "sample_format": info.sample_format,
            "scaling_coeff": None if info.scaling_coeff is None else info.scaling_coeff.tolist(),
            "volts_to_n": self.cal.volts_to_n.tolist(),
            "spindle_rpm": self.rpms[k] if 0 <= k < self.n_runs else None,
            "teeth": self._teeth(),
            # the run's cut for the lobes (the server computes them), or why there are none
            "stability": self._stability(k),
            "zero_v": None,
            "program": [],
        }

    def _stability(self, k: int) -> dict[str, Any]:
        if not 0 <= k < self.n_runs:
            return {"reason": "no run"}
        try:
            return stability_case(self.campaign, self.tests[k])
        except Exception as exc:  # noqa: BLE001 - the live view must never endanger the run
            return {"reason": f"no lobes: {exc}"[:200]}

    def _teeth(self) -> int | None:
        tool = getattr(self.campaign, "tool", None)
        n = getattr(tool, "inserts", None) or getattr(tool, "flutes", None)
        return int(n) if isinstance(n, int | float) and n > 0 else None

    def on_program(self, program: Program) -> None:
        """The program starts: its lines for the program view; the zero from the rest just
        recorded (the runner zeroes on the same rest before it starts the program)."""
        meta = dict(self._meta)
        rows = self.ring.rows_so_far()
        if len(rows) and self._info is not None:
            volts = rows.astype(float)
            if self._info.sample_format == rf.SAMPLE_FORMAT_RAW:
                volts = rf.raw_to_volts(rows, self._info.scaling_coeff)
            meta["zero_v"] = volts.mean(axis=0).tolist()
        meta["program"] = [[b.index, b.line, b.text] for b in program.blocks]
        self._line_of = {b.index: b.line for b in program.blocks}
        meta["program_name"] = program.name
        try:  # the DRO's estimate and the toolpath; a program it cannot read shows without
            path = ProgramPath(program.text, getattr(self.campaign, "machine", None), program.name)
            meta["toolpath"] = path.toolpath(5000)
            self._path = path
        except Exception as exc:  # noqa: BLE001 - the live view must never endanger the run
            meta["toolpath"] = []
            self.note("fault", f"console: the program's path is not shown: {exc}"[:300])
        self._meta = meta
        self.ring.put_meta(meta)

    def on_session_closed(self, session: _LiveSession) -> None:
        self._publish()  # the last executed blocks
        with self._lock:
            if self._session is session:
                self._session = None
                self.phase = "between runs"

    # -- the publisher thread --------------------------------------------------------------------
    def _loop(self) -> None:
        # A plain sleep on a fixed beat: it wakes half as dearly as Event.wait(timeout), and
        # close() waits at most one tick for it.
        due = time.monotonic()
        while True:
            due = max(due + TICK_S, time.monotonic())
            time.sleep(max(0.0, due - time.monotonic()))
            if self._closed.is_set():
                return
            self.guard(self._command)
            self.guard(self._publish)

    def _command(self) -> None:
        if self.ring.seq("command") <= self._cmd_done:
            return  # nothing new: no JSON read
        seq, cmd = self.ring.read_command()
        if seq <= self._cmd_done or not isinstance(cmd, dict):
            return
        self._cmd_done = seq
        what = str(cmd.get("cmd", ""))
        ok, message = self.command(what, str(cmd.get("from", ""))[:80])
        self._last_cmd = {"seq": seq, "cmd": what, "ok": ok, "message": message}

    def command(self, what: str, client: str = "") -> tuple[bool, str]:
        """Hold, resume or abort the run (``client``: the page's address, as the server saw it);
        (done, what was done or why not)."""
        s = self._session
        if what == "abort":
            who = f"client {client}" if client else "client unknown"
            # the runner holds, stops, closes the run "abort" with this as its reason
            self.stop.request(kill=True, source=f"console ({who})")
            if s is not None and s.writer is not None:
                s.writer.event(rf.EV_NOTE, f"console: abort requested by the operator ({who})")
            self.note("abort", f"console: abort requested ({who})")
            return True, "abort requested: feed hold, stop, campaign ends"
        if what not in ("hold", "resume"):
            return False, f"unknown command {what!r} (expected hold, resume or abort)"
        if s is None:
            return False, f"{what}: no run in progress"
        kind, message = (rf.EV_PAUSE, "console: feed hold") if what == "hold" else (
            rf.EV_RESUME, "console: cycle start")  # fmt: skip
        (s.inner.feed_hold if what == "hold" else s.inner.cycle_start)()
        self._held = what == "hold"
        if s.writer is not None:  # None while the rig zeroes, before the program starts
            s.writer.event(kind, message)
        self.note(kind, message)
        return True, f"{message.removeprefix('console: ')} sent"

    def _publish(self) -> None:
        self.ring.heartbeat()
        s = self._session
        now = time.monotonic()
        status: dict[str, Any] = {
            "phase": self.phase,
            "message": self.message,
            "campaign": self.campaign.name,
            "run": self._run_k + 1,
            "runs": self.n_runs,
            "run_name": self.run_names[self._run_k] if 0 <= self._run_k < self.n_runs else "",
            "elapsed_s": round(now - self._wall0, 1),
            "remaining_s": self._remaining_s(now),
            "events": None,  # spliced in below, encoded once per new event
            "command": self._last_cmd,
            "tap_errors": self.tap_errors,
        }
        if s is not None:
            status |= self._session_status(s)
        else:
            status["machine"] = {"state": "", "source": "no run in progress"}
            status["bands"] = self._bands
            ended = self.phase in ("finished", "stopped", "failed")
            # between runs abort still ends the campaign
            status["controls"] = {"hold": False, "resume": False, "abort": not ended}
        # The events (up to MAX_EVENTS, ~30 kB of JSON) were most of a tick's encoding; the
        # same bytes as encoding them in place: the first '"events":null' is the key's (no
        # earlier value is a string that could hold it unescaped).
        n, events = self._events_json
        if n != self._events_n:
            n = self._events_n  # read first: an event noted meanwhile is encoded next tick
            self._events_json = n, events = n, self.ring.dumps(list(self.events))
        data = self.ring.dumps(status).replace(b'"events":null', b'"events":' + events, 1)
        self.ring.put_status_json(data)

    def _remaining_s(self, now: float) -> float:
        k = self._run_k
        if self.phase in ("finished", "stopped") or k < 0:
            return 0.0 if k >= 0 else round(sum(self.expected_wall_s), 1)
        left = max(0.0, self.expected_wall_s[k] - (now - self._run_wall0))
        return round(left + sum(self.expected_wall_s[k + 1 :]), 1)

    def _session_status(self, s: _LiveSession) -> dict[str, Any]:
        st = getattr(s.inner, "streamer", None)
        done, total = s.inner.progress()
        now = s.clock()
        fault = s.inner.fault()
        if fault and fault != self._fault_seen:
            self._fault_seen = fault
            kind = next((k for k in ("interlock", "alarm", "overflow") if k in fault), "fault")
            self.note(kind, fault)
        if st is not None and hasattr(st, "executed_blocks"):
            # The streamer's execution starts (GRBL: seen in status reports; drip feed:
            # predicted, some still ahead): the block executing is the last one started by now.
            with contextlib.suppress(RuntimeError):  # the streamer's dict changed: next time
                spans = [x for x in st.executed_blocks()[-2000:] if x[0] >= 0 and x[1] <= now]
                self._executing = spans[-1][0] if spans else -1
                self._exec_t0 = spans[-1][1] if spans else math.nan
                # Only the blocks started in the last BANDS_S (and the one before): 25 times a
                # second this thread takes the GIL from the logger, so it keeps its work small.
                # An even cut keeps each band's alternate shading on the page.
                cut = max(0, bisect.bisect_left(spans, now - BANDS_S, key=lambda x: x[1]) - 1)
                self._bands = [[b, round(t0, 4), _jsonable(t1) if t1 <= now else None]
                               for b, t0, t1, _ in spans[cut - cut % 2 :]]  # fmt: skip
        executing = self._executing
        machine = machine_report(s.inner)
        if machine.get("pos_mm") is None and self._path is not None and executing >= 0:
            est = self._path.estimate(executing, now - self._exec_t0)
            self._dro = est or self._dro
            if self._dro:
                machine |= self._dro | {"estimated": True, "source": (
                    f"estimated from block {executing} and the program; "
                    + machine.get("source", ""))}  # fmt: skip
        if machine.get("overrides_pct"):  # GRBL sends them every 10-30 reports: the last kept
            self._overrides = machine["overrides_pct"]
        elif self._overrides and machine.get("source") == "GRBL status":
            machine["overrides_pct"] = self._overrides
        ctl = getattr(s, "adaptive_controller", None)  # set by rig.adaptive's session
        state = str(machine.get("state") or "")
        held = state.startswith(("Hold", "Door")) or (not state and self._held)
        stopped = state.startswith(("Alarm", "Idle"))
        return {
            "t_now_s": round(s.clock(), 4),
            "machine": machine,
            # the buttons that act now (the page disables the others)
            "controls": {"hold": not held and not stopped, "resume": held, "abort": True},
            "stream": {
                "sent": getattr(st, "last_sent_block", -1),
                "acknowledged": getattr(st, "last_ack_block", -1),
                "executing": executing,
                "executed": getattr(st, "last_executed_block", -1),
                "blocks_done": done,
                "blocks_total": total,
                "protocol": getattr(st, "protocol", ""),
            },
            "executing_block": executing,
            "executing_line": self._line_of.get(executing),
            "bands": self._bands,
            # the adaptive loop (rig.adaptive): target, force per revolution, overrides, state
            "adaptive": None if ctl is None else ctl.live_status(),
            "logger": self._logger_status(s, now),
        }

    def _logger_status(self, s: _LiveSession, now: float) -> dict[str, Any] | None:
        stats = getattr(s.writer, "stats", None)  # the run writer, once the program starts
        health = self._health
        return None if health is None else health.status(stats() if stats else None, now)

    # -- the end ---------------------------------------------------------------------------------
    def close(self, phase: str = "finished", message: str = "") -> None:
        """The campaign has ended (``phase``: finished, stopped, failed): say so, then stop."""
        if self._closed.is_set():
            return
        with self._lock:
            self._session = None
            self.phase, self.message = phase, message
            if phase == "finished":
                self._run_k = self.n_runs - 1
        self._closed.set()
        self._thread.join(timeout=2.0)
        self.guard(self._publish)
        self.ring.close()


@contextlib.contextmanager
def live_console(
    campaign: Campaign,
    out_root: str | Path | None = None,
    *,
    port: int = 8765,
    bind: str = "127.0.0.1",
    serve: bool = True,
) -> Iterator[LiveCampaign]:
    """Run a campaign with the console: the ring, ``live.json`` in the campaign folder, and
    (``serve``) the page server at ``http://bind:port/?token=...`` in its own process (the
    address with the session's token is printed on stderr). The server's death does not stop
    the campaign; the campaign's end (or death) is shown on the page, and the server stays
    ``LINGER_S`` after it to browse the runs (:func:`leave_server`). The ring and ``live.json``
    are removed when this ends, however it ends; a killed campaign's are removed by the next
    start (:func:`remove_stale`)."""
    import secrets

    folder = campaign_folder(campaign, out_root)
    if serve:
        check_console_extra()
        end_lingering(bind, port)
        check_port(bind, port)
    folder.mkdir(parents=True, exist_ok=True)
    remove_stale(folder)
    token = secrets.token_urlsafe(24)
    live = LiveCampaign(campaign, folder)
    pointer = folder / LIVE_FILE
    proc = None
    phase, message = "finished", ""
    try:
        pointer.write_text(json.dumps({"ring": str(live.ring.path), "pid": os.getpid(),
                                       "port": port, "bind": bind}))  # fmt: skip
        if serve:
            proc = start_server(folder, port, bind, token)
            print(f"cutlab: live console at {url_of(bind, port, token)}", file=sys.stderr,
                  flush=True)  # fmt: skip
        yield live
        if live.stop.event.is_set():
            who = live.stop.source or "no source given"
            phase, message = "stopped", f"the campaign was stopped ({who})"
    except BaseException as exc:
        phase, message = "failed", f"{type(exc).__name__}: {exc}"[:300]
        if isinstance(exc, KeyboardInterrupt):
            phase = "stopped"
        raise
    finally:
        try:
            live.close(phase, message)
        finally:
            pointer.unlink(missing_ok=True)
            with contextlib.suppress(OSError):
                live.ring.path.unlink()
            if proc is not None:
                leave_server(proc, url_of(bind, port, token))
