"""The operator's feed hold, resume and abort while ``cutlab dnc send`` streams, as senders (UGS,
CNCjs, bCNC) take them: from the keyboard and from signals.

- Keys, when stdin is a terminal (read in cbreak mode, no Enter needed, no echo): ``!`` or space =
  feed hold, ``~`` or ``r`` = resume (cycle start), ``q`` = abort. Ctrl-C stays SIGINT, which
  :func:`rig.dnc.guard.halt_on_signals` turns into the same abort.
- Signals: SIGUSR1 = feed hold, SIGUSR2 = resume (``kill -USR1 PID``), from scripts or a pendant.

What each does, by protocol:

- GRBL: hold sends ``!`` and waits (at most ``confirm_s``) for GRBL to report ``Hold``; resume
  waits for the hold to finish decelerating (``Hold:0``: GRBL ignores ``~`` before that), sends
  ``~`` and waits for ``Run`` (or ``Idle`` when nothing was left to run); abort is the streamer's
  halt: ``!`` at once, then ``Hold:0``, then the soft reset 0x18 (never a reset in motion).
- Fanuc drip feed: the line carries no feed hold, so hold and resume say to press FEED HOLD /
  CYCLE START on the control; abort stops feeding and says so (the control runs what it has).

Every action is one status line on stderr (``cutlab: feed hold (SIGUSR1) at block 152: GRBL
Hold:0``) and an entry of :attr:`OperatorControl.actions` (``cutlab dnc send --json``:
``operator_actions``). The signal handlers only queue the action: a worker thread acts, so
nothing waits inside a handler.
"""

from __future__ import annotations

import contextlib
import os
import queue
import select
import signal
import threading
import time
from collections.abc import Callable, Iterator
from types import FrameType
from typing import TYPE_CHECKING, Any, cast

from rig.dnc.errors import DncError
from rig.dnc.protocols import protocol_of

if TYPE_CHECKING:
    from rig.dnc.fanuc import FanucStreamer
    from rig.dnc.grbl import GrblStreamer

#: key -> action
KEYS = {"!": "hold", " ": "hold", "~": "resume", "r": "resume", "R": "resume", "q": "abort",
        "Q": "abort"}  # fmt: skip
#: signal name -> action
SIGNALS = {"SIGUSR1": "hold", "SIGUSR2": "resume"}


def _signal_handler(
    ctl: OperatorControl, action: str, name: str
) -> Callable[[int, FrameType | None], None]:
    """A signal handler requesting ``action`` from the signal ``name``."""

    def handle(signum: int, frame: FrameType | None) -> None:
        ctl.request(action, name)

    return handle

HELP = (
    "while sending: '!' or space = feed hold, '~' or 'r' = resume, 'q' or Ctrl-C = abort "
    "(feed hold first); SIGUSR1 = feed hold, SIGUSR2 = resume"
)
_WORDS = {"hold": "feed hold", "resume": "resume", "abort": "abort"}


class OperatorControl:
    """Feed hold / resume / abort of ``streamer`` on request (see the module docstring).

    ``say``: one status line (default: stderr); ``confirm_s``: how long to wait for GRBL to
    report the state an action asked for (wall s)."""

    def __init__(
        self,
        streamer: FanucStreamer | GrblStreamer,
        protocol: str,
        *,
        say: Callable[[str], None] | None = None,
        confirm_s: float = 3.0,
    ) -> None:
        self.streamer = streamer
        self.protocol = protocol
        self.rules = protocol_of(protocol)
        self.say = say or _stderr
        self.confirm_s = confirm_s
        self.actions: list[dict[str, Any]] = []
        self._q: queue.SimpleQueue[tuple[str, str, float]] = queue.SimpleQueue()
        self._stop = threading.Event()
        self._t0 = time.perf_counter()
        self._worker = threading.Thread(target=self._work, name="dnc-operator", daemon=True)

    # -- requests (any thread, signal handlers) ------------------------------------------------
    def request(self, action: str, source: str) -> None:
        """Queue ``action`` ("hold", "resume", "abort") from ``source`` (e.g. "key '!'")."""
        if action not in _WORDS:
            raise ValueError(f"operator action {action!r}: expected hold, resume or abort")
        if action == "abort":  # at once: the protocol's first step (GRBL: '!') must not queue
            self.streamer.interrupt(f"stopped by the operator ({source})")
        self._q.put((action, source, time.perf_counter()))

    def note(self, signal_name: str) -> None:
        """Record an abort a signal handler already made (SIGINT, SIGTERM, SIGHUP)."""
        self._q.put(("abort", signal_name, time.perf_counter()))

    def key(self, ch: str) -> None:
        if ch in KEYS:
            self.request(KEYS[ch], f"key {ch!r}")

    # -- the worker ----------------------------------------------------------------------------
    def start(self) -> OperatorControl:
        self._worker.start()
        return self

    def close(self) -> None:
        """Stop the worker after the queued actions (at most ``confirm_s`` + 1 s)."""
        self._stop.set()
        if self._worker.is_alive():
            self._worker.join(self.confirm_s + 1.0)

    def _work(self) -> None:
        while True:
            try:
                action, source, t = self._q.get(timeout=0.05)
            except queue.Empty:
                if self._stop.is_set():
                    return
                continue
            try:
                result = getattr(self, f"_{action}")(source)
            except DncError as exc:  # e.g. the port is not open yet, or is gone
                result = f"not done: {exc}"
            except Exception as exc:  # noqa: BLE001 - the worker must not die mid-stream
                result = f"not done: {type(exc).__name__}: {exc}"
            self._record(action, source, t, result)

    def _record(self, action: str, source: str, t: float, result: str) -> None:
        st = self.streamer
        block = getattr(st, "executing_block", -1)
        if block is None or block < 0:
            block = getattr(st, "last_ack_block", -1)
        entry = {"t_s": round(t - self._t0, 3), "action": action, "source": source,
                 "block": int(block), "result": result}  # fmt: skip
        self.actions.append(entry)
        at = f" at block {block}" if block >= 0 else ""
        self.say(f"cutlab: {_WORDS[action]} ({source}){at}: {result}")

    # -- the actions -----------------------------------------------------------------------------
    def _state(self) -> str:
        s = getattr(self.streamer, "last_status", None)
        return s.full_state if s is not None else ""

    def _wait_state(
        self, want: Callable[[str], bool], seconds: float, idle_ok: bool = False
    ) -> str:
        """The state of the first status report, after this call, that ``want`` accepts within
        ``seconds``, else "" (the streamer polls GRBL's status; a report that was already in
        flight does not count). ``idle_ok``: ``Idle`` from the third new report on counts too
        (nothing left to hold or run)."""
        seen = getattr(self.streamer, "last_status", None)
        new = 0
        end = time.perf_counter() + seconds
        while time.perf_counter() < end:
            s = getattr(self.streamer, "last_status", None)
            if s is not None and s is not seen:
                seen, new = s, new + 1
                if want(s.full_state) or (idle_ok and new >= 3 and s.state == "Idle"):
                    return s.full_state
            time.sleep(0.01)
        return ""

    def _hold(self, source: str) -> str:
        if not self.rules.realtime_bytes:
            return "a Fanuc takes no feed hold over the line: press FEED HOLD on the control"
        cast("GrblStreamer", self.streamer).feed_hold()  # realtime bytes: GRBL's streamer
        state = self._wait_state(lambda s: s.startswith("Hold"), self.confirm_s, idle_ok=True)
        if not state:
            return f"'!' sent; GRBL has not reported Hold within {self.confirm_s:g} s"
        return f"'!' sent: GRBL {state}"

    def _resume(self, source: str) -> str:
        if not self.rules.realtime_bytes:
            return "a Fanuc takes no cycle start over the line: press CYCLE START on the control"
        if self._state() == "Hold:1":  # GRBL ignores '~' while the hold decelerates
            self._wait_state(lambda s: s != "Hold:1", self.confirm_s)
        cast("GrblStreamer", self.streamer).cycle_start()  # realtime bytes: GRBL's streamer
        state = self._wait_state(lambda s: s in ("Run", "Jog"), self.confirm_s, idle_ok=True)
        if not state:
            now = self._state() or "nothing"
            return f"'~' sent; GRBL still reports {now} after {self.confirm_s:g} s"
        return f"'~' sent: GRBL {state}"

    def _abort(self, source: str) -> str:
        if not self.rules.realtime_bytes:
            return ("feeding stopped; a Fanuc takes no feed hold over the line: it runs what it "
                    "has buffered, press FEED HOLD or RESET on the control")  # fmt: skip
        return "'!' sent; the stream halts: Hold:0, then soft reset (0x18)"


def _stderr(msg: str) -> None:
    import sys

    print(msg, file=sys.stderr, flush=True)


class _Keyboard:
    """Keys from a terminal on ``fd`` in cbreak mode (restored on :meth:`close`)."""

    def __init__(self, fd: int, on_key: Callable[[str], None]) -> None:
        import termios
        import tty

        self.fd = fd
        self.on_key = on_key
        self._saved = termios.tcgetattr(fd)
        tty.setcbreak(fd)  # ISIG kept: Ctrl-C is still SIGINT
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read, name="dnc-keys", daemon=True)
        self._thread.start()

    def _read(self) -> None:
        while not self._stop.is_set():
            try:
                r, _, _ = select.select([self.fd], [], [], 0.05)
                if not r:
                    continue
                data = os.read(self.fd, 64)
            except (OSError, ValueError):
                return
            if not data:  # the terminal went away
                return
            for ch in data.decode("ascii", "replace"):
                self.on_key(ch)

    def close(self) -> None:
        import termios

        self._stop.set()
        self._thread.join(1.0)
        with contextlib.suppress(termios.error, OSError):
            termios.tcsetattr(self.fd, termios.TCSADRAIN, self._saved)


@contextlib.contextmanager
def operator_control(
    streamer: FanucStreamer | GrblStreamer,
    protocol: str,
    *,
    stdin_fd: int | None = 0,
    signals: bool = True,
    say: Callable[[str], None] | None = None,
) -> Iterator[OperatorControl]:
    """While the block runs: keys from ``stdin_fd`` if it is a terminal, SIGUSR1/SIGUSR2 if
    ``signals`` (main thread only), acting on ``streamer``; everything restored on the way out."""
    ctl = OperatorControl(streamer, protocol, say=say).start()
    kb = None
    old: dict[int, Any] = {}
    try:
        if stdin_fd is not None:
            with contextlib.suppress(OSError, ValueError):
                if os.isatty(stdin_fd):
                    kb = _Keyboard(stdin_fd, ctl.key)
        if signals and threading.current_thread() is threading.main_thread():
            for name, action in SIGNALS.items():
                sig = getattr(signal, name, None)
                if sig is not None:
                    old[sig] = signal.signal(sig, _signal_handler(ctl, action, name))
        yield ctl
    finally:
        for sig, h in old.items():
            signal.signal(sig, h)
        if kb is not None:
            kb.close()
        ctl.close()
