"""Serial settings per protocol, checked before opening, and opening the port with pyserial.

The port is a device name (``/dev/ttyUSB0``, the slave side of a pseudo-terminal such as
``/dev/pts/3``) or any pyserial URL (``loop://``, ``socket://host:port``, ``rfc2217://...``);
:func:`serial.serial_for_url` gives the same object for all of them, so a test swaps the machine
for a simulated controller by changing one string.

What each protocol accepts (anything else is a :class:`~rig.dnc.errors.DncError` naming the field):

- ``fanuc``: 7 or 8 data bits, any parity, 1 or 2 stop bits, a Fanuc baud rate
  (:data:`rig.dnc.protocols.FANUC_BAUDS`), flow control ``xonxoff`` (DC1/DC3), ``rtscts`` or
  ``none``; tape code ISO, or EIA (:mod:`rig.dnc.eia`) which needs 8 data bits and no UART parity.
- ``grbl``: 8N1 only, flow control ``none`` (GRBL answers ``ok``; it sends no DC1/DC3 and an
  Arduino has no RTS/CTS lines).

All settings are passed to the constructor and nothing is changed after opening. A Linux
pseudo-terminal keeps 8 data bits and no parity whatever is asked, and refuses (EINVAL) a request
for 7 bits or parity once it holds those; a pty (``/dev/pts/*``, the simulated controllers) is
therefore opened as 8 bits, no parity, with the configured stop bits — it carries the same 7-bit
ISO characters either way.
"""

from __future__ import annotations

import os
import termios
from typing import Any

import serial

from analysis.config import SerialConfig
from planning.nc.dialects import protocols
from rig.dnc.errors import DncError
from rig.dnc.protocols import protocol_of

PROTOCOLS = protocols()  # the streaming protocols of planning.nc.dialects: ("fanuc", "grbl")

#: End-of-block bytes per config value.
EOB_BYTES = {"LF": b"\n", "CRLF": b"\r\n", "CR": b"\r"}


def check_protocol(protocol: str) -> str:
    if protocol not in PROTOCOLS:
        raise DncError(f"protocol = {protocol!r}: unknown; expected one of {', '.join(PROTOCOLS)}")
    return protocol


def bits_per_char(cfg: SerialConfig) -> int:
    """Bits on the wire per character: start + data + parity + stop."""
    return 1 + cfg.bytesize + (cfg.parity != "N") + cfg.stopbits


def line_bytes_per_s(cfg: SerialConfig) -> float:
    """Characters per second the line carries at ``cfg.baudrate``."""
    return cfg.baudrate / bits_per_char(cfg)


def check_settings(cfg: SerialConfig, protocol: str, where: str = "serial") -> None:
    """Raise :class:`DncError` if ``protocol``'s controller cannot take these settings."""
    p = protocol_of(check_protocol(protocol))
    bad: list[str] = []
    if p.serial_8n1_only:
        if cfg.bytesize != 8:
            bad.append(f"{where}.bytesize = {cfg.bytesize}: {p.title} talks 8N1 only (expected 8)")
        if cfg.parity != "N":
            bad.append(f"{where}.parity = {cfg.parity!r}: {p.title} talks 8N1 only (expected 'N')")
        if cfg.stopbits != 1:
            bad.append(f"{where}.stopbits = {cfg.stopbits}: {p.title} talks 8N1 only (expected 1)")
        if cfg.flow_control != "none":
            bad.append(
                f"{where}.flow_control = {cfg.flow_control!r}: {p.title} paces the sender with "
                "'ok' answers and has no DC1/DC3 or RTS/CTS (expected 'none')"
            )
    else:
        if p.bauds is not None and cfg.baudrate not in p.bauds:
            bad.append(
                f"{where}.baudrate = {cfg.baudrate}: not a {p.title} reader/punch baud rate "
                f"(expected one of {', '.join(map(str, p.bauds))} baud)"
            )
        if cfg.code == "EIA" and (cfg.bytesize != 8 or cfg.parity != "N"):
            bad.append(
                f"{where}.code = 'EIA' with bytesize = {cfg.bytesize}, parity = {cfg.parity!r}: "
                "EIA codes use all 8 tape channels with their own parity (expected bytesize = 8, "
                "parity = 'N')"
            )
    if bad:
        raise DncError("; ".join(bad))


def is_pty(port: str) -> bool:
    """True for the slave side of a Unix98 pseudo-terminal (device majors 136-143)."""
    if port.startswith("/dev/pts/"):
        return True
    try:
        return 136 <= os.major(os.stat(port).st_rdev) <= 143
    except (OSError, ValueError):
        return False


def open_port(cfg: SerialConfig, protocol: str, read_timeout_s: float = 0.02) -> serial.SerialBase:
    """Check the settings and open the port; a port that cannot be opened is a clear DncError."""
    check_settings(cfg, protocol)
    pty = is_pty(cfg.port)
    kw: dict[str, Any] = dict(
        baudrate=cfg.baudrate,
        bytesize=8 if pty else cfg.bytesize,
        parity="N" if pty else cfg.parity,
        stopbits=cfg.stopbits,
        timeout=read_timeout_s,
        write_timeout=cfg.timeout_s,
        xonxoff=cfg.flow_control == "xonxoff" and not cfg.xonxoff_in_streamer,
        rtscts=cfg.flow_control == "rtscts",
    )
    try:
        return serial.serial_for_url(cfg.port, **kw)
    except (serial.SerialException, OSError, ValueError, termios.error) as exc:
        raise DncError(
            f"serial.port = {cfg.port!r}: cannot open ({exc}); check the port name in the machine "
            "config or --port, or start a simulated controller with `cutlab dnc sim-controller`"
        ) from None
