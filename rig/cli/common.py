"""Small helpers shared by the command modules: the argument types that keep bad numbers at the
edge, the one-line errors, JSON and table output (formats: :mod:`analysis.output`), the
progress bar and heartbeat (:mod:`rig.terminal`)."""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from analysis.output import TABLE_CELL_MAX, finite_json, json_default, table_lines
from rig.terminal import Heartbeat, Progress

#: analysis.validation.MAGNITUDE_LIMIT, the bound of every config number (not imported: pydantic
#: would slow `cutlab --help`; tests/test_faults.py checks the two agree)
MAGNITUDE_LIMIT = 1e9

# ---------------------------------------------------------------------------- argument types


def number(
    unit: str = "", lo: float | None = None, hi: float = MAGNITUDE_LIMIT, *,
    lo_open: bool = False, integer: bool = False,
) -> Callable[[str], float]:  # fmt: skip
    """An argparse ``type=``: a finite number (an integer if ``integer``) in [lo, hi] (lo
    excluded if ``lo_open``); anything else is one line naming the value and the range."""
    kind = "a whole number" if integer else "a finite number"
    rng = "" if lo is None else f" {'>' if lo_open else '>='} {lo:g}"
    rng += f"{' and' if rng else ''} <= {hi:g}"
    what = f"{kind}{rng}{f' ({unit})' if unit else ''}"

    def parse(text: str) -> float:
        try:
            v = int(text) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {what}") from None
        bad = not math.isfinite(v) or v > hi or (
            lo is not None and (v <= lo if lo_open else v < lo)
        )  # fmt: skip
        if bad:
            raise argparse.ArgumentTypeError(f"{text!r}: expected {what}")
        return v

    parse.__name__ = "int" if integer else "float"  # argparse names the type in its messages
    return parse


def positive(unit: str = "", hi: float = MAGNITUDE_LIMIT) -> Callable[[str], float]:
    """A finite number > 0."""
    return number(unit, 0, hi, lo_open=True)


def nonnegative(unit: str = "", hi: float = MAGNITUDE_LIMIT) -> Callable[[str], float]:
    """A finite number >= 0."""
    return number(unit, 0, hi)


def count(lo: int = 1, hi: float = MAGNITUDE_LIMIT, unit: str = "") -> Callable[[str], int]:
    """A whole number >= ``lo``."""
    return number(unit, lo, hi, integer=True)  # type: ignore[return-value]


#: picture suffixes matplotlib writes (checked here so a typo fails before the work, not after)
IMAGE_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg", ".tif", ".tiff", ".webp", ".eps")


def image_file(text: str) -> Path:
    """An argparse ``type=``: a picture path whose suffix matplotlib can write."""
    p = Path(text)
    if p.suffix.lower() not in IMAGE_SUFFIXES:
        raise argparse.ArgumentTypeError(
            f"{text!r}: a picture needs one of the suffixes {', '.join(IMAGE_SUFFIXES)}"
        )
    return p


def error_line(message: str) -> None:
    """Write ``cutlab: error: MESSAGE`` to stderr as exactly one line: characters that are not
    printable (a control character typed into an argument or a file name, which a terminal or
    a log reader may take for a line break) are shown escaped, as Python writes them."""
    shown = "".join(c if c.isprintable() else repr(c)[1:-1] for c in message)
    sys.stderr.write(f"cutlab: error: {shown}\n")


class Parser(argparse.ArgumentParser):
    """The command's parser: a usage error is one line ``cutlab: error: ...`` (exit 2), like
    every other error, with the command and a pointer to its --help."""

    def error(self, message: str) -> None:  # type: ignore[override]
        cmd = self.prog.removeprefix("cutlab").strip()
        error_line(f"{cmd + ': ' if cmd else ''}{message} (see `{self.prog} --help`)")
        sys.exit(2)


# ---------------------------------------------------------------------------- output


def print_json(obj: Any) -> None:
    """Write ``obj`` as strict JSON to stdout (numpy scalars and arrays allowed; NaN and
    infinity become null with a ``<key>_reason``, see :func:`analysis.output.finite_json`)."""
    json.dump(finite_json(obj), sys.stdout, indent=2, default=json_default, allow_nan=False)
    sys.stdout.write("\n")


def show(
    as_json: bool, obj: Any, lines: Callable[[], Sequence[str]] = list, code: int = 0, *,
    notes: Callable[[], Sequence[str | None]] = list, after: Sequence[str | None] = (),
) -> int:  # fmt: skip
    """A command's result: ``obj`` as JSON on stdout if ``as_json``, else the ``notes()`` on
    stderr, the ``lines()`` it renders to on stdout and the notes ``after`` on stderr (a note
    None is none); returns ``code`` (the command's exit status)."""
    if as_json:
        print_json(obj)
        return code
    for note in notes():
        if note is not None:
            status(note)
    print_lines(lines())
    for note in after:
        if note is not None:
            status(note)
    return code


def print_notes(cmd: str, out: Mapping[str, Any], wrote: Sequence[str] = ()) -> None:
    """A result's notes on stderr: ``CMD: wrote FILE`` for each of its keys ``wrote`` it has (a
    list of files on one line), then ``CMD: warning: W`` for each of its ``warnings``."""
    for key in (k for k in wrote if k in out):
        files = out[key]
        status(f"{cmd}: wrote {', '.join(files) if isinstance(files, list) else files}")
    for w in out.get("warnings", ()):
        status(f"{cmd}: warning: {w}")


def bar_note(bar: Progress) -> Callable[[str], None]:
    """A job's status callback once its steps are done: the bar gives way to the status line."""

    def note(message: str) -> None:
        bar.close()
        status(message)

    return note


def noter(cmd: str) -> Callable[[str], None]:
    """A package's ``note`` callback: each note a status line ``CMD: NOTE`` on stderr."""
    return lambda message: status(f"{cmd}: {message}")


def print_table(rows: Sequence[Mapping[str, Any]], floatfmt: str = ".4g",
                cell_max: int = TABLE_CELL_MAX) -> None:  # fmt: skip
    """A plain aligned text table of dict rows to stdout (:func:`analysis.output.table_lines`)."""
    print_lines(table_lines(rows, floatfmt, cell_max))


def print_lines(lines: Sequence[str]) -> None:
    """Lines a package rendered, to stdout."""
    for line in lines:
        print(line)


def status(msg: str) -> None:
    """Status and progress go to stderr so stdout stays machine-readable."""
    print(msg, file=sys.stderr, flush=True)


#: commands that serve or wait on a device until stopped (their own output says they are
#: alive), or stream with their own plain progress lines (rig/dnc/progress.py)
_NO_HEARTBEAT = {"console", "dnc"}


def heartbeat_for(args: argparse.Namespace) -> Heartbeat:
    """The heartbeat of the command ``args`` names (``cutlab main`` wraps every command)."""
    names = vars(args)
    words = [names[k] for k in ("command", *sorted(k for k in names if k.endswith("_command")))
             if isinstance(names.get(k), str)]  # fmt: skip
    quiet = (not words or words[0] in _NO_HEARTBEAT or bool(getattr(args, "quiet", False))
             or bool(getattr(args, "live", False)))  # fmt: skip
    return Heartbeat(" ".join(["cutlab", *words]), quiet=quiet)
