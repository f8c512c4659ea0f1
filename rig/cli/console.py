"""`cutlab console [CAMPAIGN_DIR|RUN.h5]` — the live lab console in a local web page
(:mod:`rig.console.server`: what it serves, and the session's token every request needs)."""

from __future__ import annotations

import argparse

from rig.cli.common import count, nonnegative, status
from rig.cli.options import command

DEFAULT_PORT = 8765


#: ``--port`` and ``--bind`` (shared with ``campaign run --live``)
SERVER = [
    ("--port", count(1, 65535, "TCP port"), DEFAULT_PORT,
     f"TCP port of the page (default {DEFAULT_PORT})"),
    ("--bind", None, "127.0.0.1", "address to listen on (default 127.0.0.1, this computer only)"),
]  # fmt: skip


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's command to ``sub``."""
    command(sub, "console", "the live lab console in a local web page", [
        ("target", None, ".", "campaign folder or run file (.h5); default: the current folder",
         {"nargs": "?"}),
        SERVER,
        ("--linger-s", nonnegative("s"), None, "exit this long after the campaign process is gone "
         "(default: never)"),
        ("--quiet", bool, None, "only the address (with its token) on stderr"),
    ], _console)  # fmt: skip


def warn_bind(bind: str) -> None:
    if bind not in ("127.0.0.1", "localhost", "::1"):
        status(f"cutlab: warning: the console listens on {bind}: anyone who reaches it with the "
               "token in its address can hold or abort the machine")  # fmt: skip


def _console(args: argparse.Namespace) -> int:
    from rig.console.live import check_console_extra, check_port

    check_console_extra()
    from rig.console.server import resolve_target, serve

    resolve_target(args.target)  # bad input: one line before anything listens
    check_port(args.bind, args.port)
    warn_bind(args.bind)

    def tell(url: str) -> None:  # once it listens; the token is the way in, so even --quiet
        status(f"cutlab: console at {url}" + ("" if args.quiet else " (Ctrl-C to stop)"))

    serve(args.target, args.port, args.bind, args.linger_s, on_listening=tell)
    return 0
