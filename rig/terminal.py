"""Progress of a long command on stderr: a tqdm bar on a terminal, else a plain line every few
seconds (:class:`Progress`), and a heartbeat line while a command works without a count of its own
(:class:`Heartbeat`, :func:`progress_note`). The commands of :mod:`rig.cli` use them."""

from __future__ import annotations

import contextlib
import math
import sys
import time
from collections.abc import Callable
from typing import Any

__all__ = ["Heartbeat", "Progress", "progress_note"]


class Progress:
    """Progress of a long command on stderr, made at the first report (nothing shows when the
    input is refused before work starts). On a terminal it is one tqdm bar; otherwise (a log
    file, CI, a service) a plain line every :attr:`interval_s` seconds, e.g.
    ``reducing runs: 12/23 run (52 %), 8 s``, and a last one at the end if any was printed.

    Call it as ``bar(done, total)`` (a count or a position such as seconds recorded) or
    ``bar.step(note)`` (one more step of unknown count); use it as a context manager.
    """

    #: seconds between the plain lines when stderr is not a terminal
    interval_s = 5.0

    def __init__(self, desc: str, unit: str = "it", total: float | None = None,
                 quiet: bool = False, **tqdm_kw: Any) -> None:  # fmt: skip
        self.desc, self.unit, self.quiet = desc, unit, quiet
        self._kw = dict(desc=desc, unit=unit, total=total, file=sys.stderr, leave=False,
                        disable=quiet, **tqdm_kw)  # fmt: skip
        self.bar: Any = None
        self.n: float = 0
        self.total = total
        self.note = ""
        self._plain = not quiet and not _isatty(sys.stderr)
        self._t0 = time.monotonic()
        self._last: float | None = None  # when the last plain line went out

    def _open(self) -> Any:
        _work_started()  # the first report: the command's heartbeat may speak from now on
        if self.bar is None and not self._plain:
            from tqdm import tqdm

            self.bar = tqdm(**self._kw)
        return self.bar

    def __call__(self, done: float, total: float | None = None) -> None:
        if total is not None:
            self.total = total
        self.n = done
        bar = self._open()
        if bar is not None:
            if total is not None:
                bar.total = total
            bar.n = done
            bar.refresh()
        self._line()

    def step(self, note: str = "") -> None:
        self.n += 1
        self.note = note or self.note
        bar = self._open()
        if bar is not None:
            if note:
                bar.set_postfix_str(note, refresh=False)
            bar.update()
        self._line()

    def _line(self, force: bool = False) -> None:
        if not self._plain:
            return
        now = time.monotonic()
        if not force and now - (self._last if self._last is not None else self._t0) < (
            self.interval_s
        ):
            return
        self._last = now
        n = f"{self.n:g}"
        if self.total:
            n += f"/{self.total:g} {self.unit} ({100 * self.n / self.total:.0f} %)"
        else:
            n += f" {self.unit}"
        note = f" [{self.note}]" if self.note else ""
        print(f"{self.desc}: {n}{note}, {now - self._t0:.0f} s", file=sys.stderr, flush=True)
        _last_line[0] = now

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
        if self._last is not None:  # the log shows where it ended
            self._line(force=True)
            self._last = None

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


#: when the last plain progress line went to stderr (time.monotonic), from any helper here
_last_line: list[float] = [-math.inf]


class Heartbeat:
    """A plain line on stderr every :attr:`interval_s` seconds while a command works and stderr
    is not a terminal (a log, CI, a service), for commands without a progress count of their
    own, or between their counts: ``cutlab campaign run: working, 25 s [run 3 of 8]``. Quiet
    until the work starts (:func:`progress_note` or a :class:`Progress` report: a refused input
    stays one line however slow the start), while a :class:`Progress` line went out within the
    interval, and for a command that ends within it. ``note`` (a string or a function giving
    one) says where the work is. A daemon thread that ends at :meth:`close` (within a second)."""

    interval_s = 5.0

    def __init__(self, desc: str, quiet: bool = False) -> None:
        import threading

        self.desc = desc
        self.note: str | Callable[[], str] = ""
        self._t0 = time.monotonic()
        self._armed: float | None = None  # when the work started
        self._stop = threading.Event()
        self._thread = None
        if not quiet and not _isatty(sys.stderr):
            self._thread = threading.Thread(target=self._beat, name="cutlab-heartbeat",
                                            daemon=True)  # fmt: skip
            self._thread.start()

    def _beat(self) -> None:
        while not self._stop.wait(min(1.0, self.interval_s)):
            now = time.monotonic()
            if self._armed is None or now - max(self._armed, _last_line[0]) < self.interval_s:
                continue
            try:
                note = self.note() if callable(self.note) else self.note
            except Exception:  # noqa: BLE001 - a note that cannot be read is left out
                note = ""
            with contextlib.suppress(ValueError, OSError):  # stderr closed under us
                print(f"{self.desc}: working, {now - self._t0:.0f} s{f' [{note}]' if note else ''}",
                      file=sys.stderr, flush=True)  # fmt: skip
            _last_line[0] = now

    def arm(self) -> None:
        """The work has started (input checked): lines may follow from now on."""
        if self._armed is None:
            self._armed = time.monotonic()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)

    def __enter__(self) -> Heartbeat:
        _current_heartbeat.append(self)
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
        with contextlib.suppress(ValueError):
            _current_heartbeat.remove(self)


_current_heartbeat: list[Heartbeat] = []


def progress_note(note: str | Callable[[], str]) -> None:
    """Say where a long command is (shown by the running :class:`Heartbeat`, if any)."""
    if _current_heartbeat:
        _current_heartbeat[-1].note = note
        _current_heartbeat[-1].arm()


def _work_started() -> None:
    if _current_heartbeat:
        _current_heartbeat[-1].arm()


def _isatty(stream: Any) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False
