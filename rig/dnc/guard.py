"""Holding the machine when the streamer is stopped from outside: signals and a watchdog.

- :func:`halt_on_signals`: while a stream runs, SIGINT (Ctrl-C), SIGTERM and SIGHUP (the terminal
  closed) call the streamer's :meth:`~rig.dnc._stream.StreamerBase.interrupt`: GRBL gets its
  feed hold ``!`` at once, then the stream halts cleanly (Hold:0, soft reset) and ends with fault
  ``interrupted``. A second signal raises KeyboardInterrupt (no more waiting; the ``!`` is sent
  again on the way out).
- :class:`HoldGuard`: a small watchdog process holding a duplicate of the port's file descriptor.
  It waits on a pipe from the streamer; if the pipe closes without the streamer saying it ended
  cleanly (the process crashed or was killed, even with SIGKILL), it writes ``!`` to the port.
  It ignores SIGINT/SIGTERM/SIGHUP and lives in its own session, so what stops the streamer does
  not stop it first; it exits as soon as its pipe closes.
"""

from __future__ import annotations

import contextlib
import signal
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rig.dnc._stream import StreamerBase

_CHILD = r"""
import os, signal, sys
for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
    signal.signal(s, signal.SIG_IGN)
fd = int(sys.argv[1])
sys.stdout.write("r")
sys.stdout.flush()
data = sys.stdin.buffer.read(1)
if data != b"x":
    try:
        os.write(fd, b"!")
    except OSError:
        pass
"""


class HoldGuard:
    """The watchdog process (see the module docstring); :meth:`start_for` a pyserial port."""

    def __init__(self, fd: int) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-I", "-S", "-c", _CHILD, str(fd)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            pass_fds=(fd,),
            start_new_session=True,
        )
        assert self.proc.stdout is not None
        self.proc.stdout.read(1)  # armed: its signal handlers are in place

    @classmethod
    def start_for(cls, ser: Any) -> HoldGuard | None:
        """A guard on ``ser``'s file descriptor; None for ports without one (pyserial URLs)."""
        try:
            fd = ser.fileno()
        except (AttributeError, OSError, ValueError, TypeError):
            return None
        if not isinstance(fd, int) or fd < 0:
            return None
        return cls(fd)

    def release(self, hold: bool = False) -> None:
        """The stream ended: tell the watchdog (``hold`` True: it sends ``!``), wait for it."""
        stdin = self.proc.stdin
        with contextlib.suppress(OSError, ValueError):
            if stdin is not None:
                stdin.write(b"!" if hold else b"x")
                stdin.close()
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(timeout=5)
        if self.proc.stdout is not None:
            self.proc.stdout.close()


@contextlib.contextmanager
def halt_on_signals(
    streamer: StreamerBase,
    signals: tuple[int, ...] | None = None,
    on_signal: Callable[[str], None] | None = None,
) -> Iterator[None]:
    """While the block runs, the ``signals`` (default SIGINT, SIGTERM, SIGHUP) interrupt
    ``streamer`` instead of killing the process (main thread only; elsewhere a no-op).
    ``on_signal(name)`` is told of the first one (after the interrupt: it must not block)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    if signals is None:
        signals = tuple(
            s for s in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None)) if s
        )

    def handler(signum: int, frame: object) -> None:
        name = signal.Signals(signum).name
        if streamer.interrupted:
            raise KeyboardInterrupt  # the second one: stop waiting
        streamer.interrupt(f"{name} received")
        if on_signal is not None:
            on_signal(name)

    old = {}
    for s in signals:
        old[s] = signal.signal(s, handler)
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)
