"""The ``cutlab`` command: one console script whose subcommands are thin and call the packages.

Each command group lives in its own module here with a ``register(subparsers)`` function; heavy
imports happen inside the handlers so that ``cutlab --help`` stays fast. Results go to stdout,
status and progress to stderr. An error caused by input (any :class:`analysis.errors.CutlabError`)
prints its message and exits with status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import functools
import importlib
import sys

from analysis import __version__
from analysis.errors import CutlabError

# Top-level groups, in help order. ``plan`` is a group whose subcommands live in plan_*.py.
GROUPS = ("demo", "nc", "daq", "data", "dnc", "analyze", "rules", "campaign", "console", "catalog")
PLAN_COMMANDS = ("plan_rough", "plan_feed", "plan_orient", "plan_check")


def build_parser() -> argparse.ArgumentParser:
    from rig.cli.common import Parser

    parser = Parser(
        prog="cutlab",
        description="Hardware-in-the-loop machining experiments (run `cutlab demo` to start).",
    )
    parser.add_argument("--version", action="version", version=f"cutlab {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in GROUPS:
        importlib.import_module(f"rig.cli.{name}").register(sub)
    plan = sub.add_parser("plan", help="roughing levels, feed post-processing, 5-axis orientation")
    plan_sub = plan.add_subparsers(dest="plan_command", metavar="PLAN_COMMAND")
    plan_sub.required = True
    for name in PLAN_COMMANDS:
        importlib.import_module(f"rig.cli.{name}").register(plan_sub)
    return parser

_parser = functools.cache(build_parser)  # once per process: tests call main ~1 200 times


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    from rig.cli.common import error_line, heartbeat_for

    try:
        with heartbeat_for(args):  # a line every 5 s on stderr when it is not a terminal
            return int(args.func(args) or 0)
    except CutlabError as exc:
        # one line, always: a message with several problems (one per field) joined by "; "
        error_line("; ".join(line.strip() for line in str(exc).split("\n") if line.strip()))
        return 2
    except (IsADirectoryError, NotADirectoryError, PermissionError) as exc:
        # a path given where a file is written or read that cannot be one (e.g. `-o` naming
        # a folder): the file and the system's reason, one line
        where = exc.filename2 or exc.filename or ""
        error_line(f"{where}: {exc.strerror or exc}")
        return 2
    except ValueError as exc:
        if "null byte" not in str(exc):
            raise
        # a path with a NUL character reaches os/h5py calls that refuse it this way
        error_line("a file name holds a NUL character")
        return 2
    except KeyboardInterrupt:
        print("cutlab: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader went away (`cutlab nc motions x.nc | head`): stop quietly, as Unix tools do.
        # Point stdout at devnull so the interpreter's final flush does not raise again.
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except OSError as exc:
        import errno

        if exc.errno not in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):
            raise
        # a full disk (or ulimit -f) under a file the command writes: where, and the free bytes
        from pathlib import Path

        from rig.log import disk_full_reason

        where = exc.filename or ""
        why = disk_full_reason(exc.errno, Path(where).parent if where else Path.cwd())
        error_line(f"{where}: {why}" if where else why)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
