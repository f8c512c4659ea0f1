"""An open serial port with a reader thread: DC1/DC3 gating, DC2/DC4, pacing, loss detection.

Many USB-serial adapters ignore the kernel's XON/XOFF, so the streamer handles DC1/DC3 itself: a
reader thread watches every byte the controller sends, closes a gate on DC3 and opens it on DC1,
and the writer sends small chunks, waiting on the gate before each one, so a stop lands within one
chunk (plus the thread wake-up) of the DC3. DC2/DC4 (the controller starts/ends punching, i.e.
sending a program or a remote request) and all other bytes are handed to callbacks.

Pacing: a real UART sends no faster than the baud rate and keeps only a small FIFO, so a gate in
front of it stops the line quickly. A pseudo-terminal has no line rate and buffers 16 KiB, so on a
pty the writer paces itself at the line rate (``pace_bytes_per_s``) to behave like the UART.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable

import serial

DC1, DC2, DC3, DC4 = 0x11, 0x12, 0x13, 0x14


class LinkLost(Exception):
    """The port went away (unplugged adapter, closed pty)."""


class LinkTimeout(Exception):
    """The gate stayed closed (XOFF or CTS off) or a write blocked past the timeout."""


class SerialLink:
    """Reader thread + gated, paced writer over one open pyserial port.

    soft_flow : handle DC1/DC3 here (gate); otherwise they are passed on as data
    cts_flow : also wait for CTS before each chunk where the port reports modem lines
    pace_bytes_per_s : at most this many bytes per wall second (None: as fast as the port takes)
    on_data : called from the reader thread with every received byte string (flow bytes removed)
    on_control : called from the reader thread with DC2 / DC4
    """

    def __init__(
        self,
        ser: serial.SerialBase,
        *,
        soft_flow: bool = False,
        cts_flow: bool = False,
        pace_bytes_per_s: float | None = None,
        chunk_bytes: int | None = None,
        on_data: Callable[[bytes], None] | None = None,
        on_control: Callable[[int], None] | None = None,
    ) -> None:
        self.ser = ser
        self.soft_flow = soft_flow
        self.cts_flow = cts_flow
        self.pace = pace_bytes_per_s
        # About 2 ms of line per chunk, between 4 and 64 bytes: small enough for a quick stop.
        self.chunk = chunk_bytes or int(min(64, max(4, (pace_bytes_per_s or 8000) * 2e-3)))
        self.on_data = on_data
        self.on_control = on_control
        self.xon = threading.Event()  # set: the controller lets us send
        self.xon.set()
        self.xoff = threading.Event()  # set while stopped by DC3 (the complement, to wait on)
        self.dc1_seen = threading.Event()
        self.lost = threading.Event()
        self.lost_reason = ""
        self.xoff_count = 0
        self.bytes_written = 0  # program data (gated, paced)
        self.realtime_bytes = 0  # real-time commands (GRBL ? ! ~ 0x18)
        self._stop = threading.Event()
        self._next_t = 0.0
        self._wlock = threading.Lock()
        self._rtlock = threading.Lock()  # real-time bytes from several threads (poll, overrides)
        self._thread = threading.Thread(target=self._read_loop, name="dnc-reader", daemon=True)

    # -- reader ---------------------------------------------------------------------------------
    def start(self) -> SerialLink:
        self._thread.start()
        return self

    def _read_loop(self) -> None:
        ser = self.ser
        while not self._stop.is_set():
            try:
                data = ser.read(max(1, ser.in_waiting))
            except (serial.SerialException, OSError, TypeError, AttributeError) as exc:
                if not self._stop.is_set():
                    self._mark_lost(f"port read failed: {exc}")
                return
            if data:
                self._handle(data)

    def _handle(self, data: bytes) -> None:
        out = bytearray()
        for b in data:
            if self.soft_flow and b == DC3:
                if self.xon.is_set():
                    self.xoff_count += 1
                self.xon.clear()
                self.xoff.set()
            elif self.soft_flow and b == DC1:
                self.dc1_seen.set()
                self.xoff.clear()
                self.xon.set()
            elif b in (DC2, DC4) and self.on_control is not None:
                if out and self.on_data is not None:
                    self.on_data(bytes(out))
                out.clear()
                self.on_control(b)
            else:
                out.append(b)
        if out and self.on_data is not None:
            self.on_data(bytes(out))

    def _mark_lost(self, reason: str) -> None:
        self.lost_reason = reason
        self.lost.set()
        self.xon.set()  # wake a writer waiting on the gate so it sees the loss

    # -- writer ---------------------------------------------------------------------------------
    def write(self, data: bytes, timeout_s: float) -> None:
        """Send ``data`` through the gate in paced chunks; raise LinkTimeout / LinkLost."""
        with self._wlock:
            for i in range(0, len(data), self.chunk):
                self._send_chunk(data[i : i + self.chunk], timeout_s)

    def _send_chunk(self, chunk: bytes, timeout_s: float) -> None:
        if self.lost.is_set():
            raise LinkLost(self.lost_reason)
        if not self.xon.is_set() and not self.xon.wait(timeout_s):
            raise LinkTimeout(f"controller held XOFF (DC3) for {timeout_s:g} s")
        if self.lost.is_set():
            raise LinkLost(self.lost_reason)
        if self.cts_flow:
            self._wait_cts(timeout_s)
        if self.pace:
            # Keep the average at the pace: a late wake-up is caught up, but by at most one
            # chunk's worth (so a burst never exceeds two chunks on the wire).
            now = time.perf_counter()
            if self._next_t > now:
                self._stop.wait(self._next_t - now)
            else:
                self._next_t = max(self._next_t, now - self.chunk / self.pace)
            self._next_t += len(chunk) / self.pace
        self._raw_write(chunk)

    def _wait_cts(self, timeout_s: float) -> None:
        t_end = time.perf_counter() + timeout_s
        while True:
            try:
                if self.ser.cts:
                    return
            except (OSError, serial.SerialException):
                self.cts_flow = False  # no modem lines (a pty): leave CTS to the kernel
                return
            if time.perf_counter() > t_end:
                raise LinkTimeout(f"CTS stayed off for {timeout_s:g} s")
            self._stop.wait(0.001)

    def _raw_write(self, data: bytes, realtime: bool = False) -> None:
        try:
            self.ser.write(data)
        except serial.SerialTimeoutException:
            raise LinkTimeout(
                f"write blocked for {self.ser.write_timeout} s (flow control held)"
            ) from None
        except (serial.SerialException, OSError, TypeError, AttributeError) as exc:
            self._mark_lost(f"port write failed: {exc}")
            raise LinkLost(self.lost_reason) from None
        if realtime:
            self.realtime_bytes += len(data)
        else:
            self.bytes_written += len(data)

    def write_now(self, data: bytes) -> None:
        """Write bypassing gate and pacing (GRBL real-time commands; counted apart)."""
        if self.lost.is_set():
            raise LinkLost(self.lost_reason)
        with self._rtlock:  # not the writer's lock: a line held by XOFF or pacing must not wait
            self._raw_write(data, realtime=True)

    def close(self) -> None:
        self._stop.set()
        with contextlib.suppress(Exception):
            self.ser.cancel_read()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        with contextlib.suppress(Exception):
            self.ser.close()
