"""`cutlab console [CAMPAIGN_DIR|RUN.h5]` — the live lab console in a local web page.

cutlab console out/quick                  # a campaign folder: live while it runs, then its runs
cutlab console out/quick/runs/000-a.h5    # browse one run file by block
cutlab console out/quick --port 9000 --bind 0.0.0.0   # reachable from the network (warns)

`cutlab campaign run CONFIG --live [--port P]` starts the same page beside a campaign (it stays
10 minutes after the campaign, `CUTLAB_CONSOLE_LINGER_S`, to browse the runs). The address
printed carries the session's token (`http://127.0.0.1:8765/?token=...`): the page, its data and
its feed hold / resume / abort answer only with it, always (also with `--bind`).
"""

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
