"""Small helpers shared by the command modules: JSON output, human tables, the progress bar,
and the argument types that keep bad numbers at the edge."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

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


def _default(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if hasattr(o, "model_dump"):
        return o.model_dump()
    if hasattr(o, "__fspath__"):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def finite_json(obj: Any) -> Any:
    """``obj`` with every NaN or infinite float turned into None (strict JSON has neither).

    Where a mapping's value is replaced and it holds no ``<key>_reason`` yet, one is added
    saying what the value was (``"r2": null, "r2_reason": "not a number (nan)"``); a producer
    that knows why (``"one run"``) sets that reason itself. Numpy values become plain ones.
    """
    if isinstance(obj, Mapping):
        out: dict[Any, Any] = {}
        for k, v in obj.items():
            out[k] = finite_json(v)
            if out[k] is None and _nonfinite(v) and f"{k}_reason" not in obj:
                out[f"{k}_reason"] = _why(v)
        return out
    if isinstance(obj, list | tuple):
        return [finite_json(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return finite_json(obj.tolist())
    if isinstance(obj, float | np.floating):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, np.generic):
        return obj.item()
    if hasattr(obj, "model_dump"):
        return finite_json(obj.model_dump())
    return obj


def _nonfinite(v: Any) -> bool:
    return isinstance(v, float | np.floating) and not math.isfinite(v)


def _why(v: float) -> str:
    if math.isnan(v):
        return "not a number (undefined for this input)"
    return f"unbounded ({'+' if v > 0 else '-'}infinity)"


def print_json(obj: Any) -> None:
    """Write ``obj`` as strict JSON to stdout (numpy scalars and arrays allowed; NaN and
    infinity become null with a ``<key>_reason``, see :func:`finite_json`)."""
    json.dump(finite_json(obj), sys.stdout, indent=2, default=_default, allow_nan=False)
    sys.stdout.write("\n")


#: widest cell of a text table; a longer value is folded onto continuation lines (the whole
#: value is in --json), so one wide cell (a conditions dict) does not pad every row
TABLE_CELL_MAX = 60


def print_table(rows: Sequence[Mapping[str, Any]], floatfmt: str = ".4g",
                cell_max: int = TABLE_CELL_MAX) -> None:  # fmt: skip
    """A plain aligned text table of dict rows to stdout; a cell longer than ``cell_max``
    characters is folded onto continuation lines (at ``, `` or spaces where it can)."""
    if not rows:
        print("(no rows)")
        return
    cols = list(rows[0])

    def fmt(v: Any, nested: bool = False) -> str:
        if isinstance(v, float | np.floating):
            x = float(v)
            if x.is_integer() and abs(x) < 1e12:
                return str(int(x))  # 30000, not 3e+04
            return format(x, floatfmt)
        if isinstance(v, Mapping):  # {'a': 1} -> a=1, b=2 (folds at the commas)
            text = ", ".join(f"{k}={fmt(x, True)}" for k, x in v.items())
            return f"{{{text}}}" if nested else text
        return " ".join(str(v).split("\n"))

    cells = [[_fold(fmt(r.get(c, "")), cell_max) for c in cols] for r in rows]
    widths = [max(len(c), *(len(ln) for row in cells for ln in row[i])) for i, c in enumerate(cols)]
    print("  ".join(c.ljust(w) for c, w in zip(cols, widths)))
    for row in cells:
        for k in range(max(len(lines) for lines in row)):
            print("  ".join((lines[k] if k < len(lines) else "").ljust(w)
                            for lines, w in zip(row, widths)))  # fmt: skip


def _fold(text: str, width: int) -> list[str]:
    """``text`` as lines of at most ``width`` characters (broken at spaces where it can)."""
    if len(text) <= width:
        return [text]
    import textwrap

    return textwrap.wrap(text, width, break_long_words=True, break_on_hyphens=False) or [""]


def status(msg: str) -> None:
    """Status and progress go to stderr so stdout stays machine-readable."""
    print(msg, file=sys.stderr, flush=True)


_NOT_FINITE = "not a finite number (a condition is a number or a name)"


def parse_conditions(items: list[str]) -> dict[str, Any]:
    """``--conditions``: one JSON object, or KEY=VALUE pairs as `cutlab analyze forces` takes
    them (numbers become numbers: ``spindle_rpm=600 tool=phi10-flat``)."""
    from analysis.errors import ConfigError

    if not items:
        return {}
    if len(items) == 1 and items[0].lstrip().startswith("{"):
        try:
            obj = json.loads(items[0])
        except json.JSONDecodeError as exc:
            raise ConfigError(f"--conditions {items[0]!r}: not a JSON object ({exc})") from None
        if not isinstance(obj, dict):
            raise ConfigError(f"--conditions {items[0]!r}: expected a JSON object")
        for key, val in obj.items():
            if isinstance(val, float) and not math.isfinite(val):
                raise ConfigError(f"--conditions: {key} = {val}: {_NOT_FINITE}")
        return obj
    out: dict[str, Any] = {}
    for item in items:
        key, sep, val = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ConfigError(
                f"--conditions {item!r}: expected KEY=VALUE (e.g. spindle_rpm=600) or one JSON "
                "object"
            )
        if key in out:
            raise ConfigError(f"--conditions: {key} given twice")
        out[key] = _number_or_text(val.strip())
        if isinstance(out[key], float) and not math.isfinite(out[key]):  # never stored as text
            raise ConfigError(f"--conditions {item!r}: {key} = {out[key]}: {_NOT_FINITE}")
    return out


def _number_or_text(text: str) -> int | float | str:
    """600 -> 600, 0.236 -> 0.236, phi10-flat -> 'phi10-flat' (nan/inf become float nan/inf:
    the caller refuses them)."""
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            continue
    return text


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


# ---------------------------------------------------------------------------- user catalogues


def add_catalog_options(p: argparse.ArgumentParser) -> None:
    """``--tools FILE`` / ``--materials FILE`` (issue 17: user catalogues next to the data, never
    edits inside the install), applied around the command's ``func``: call it after
    ``p.set_defaults(func=...)``."""
    run = p.get_default("func")
    if run is None:
        raise RuntimeError(f"{p.prog}: add_catalog_options needs set_defaults(func=...) first")
    p.add_argument("--tools", dest="catalog_tools", type=Path, metavar="FILE",
                   help="your tool catalogue (TOML, [tools.NAME]), read before "
                   "configs/tools.toml: a name in it shadows the shipped one")  # fmt: skip
    p.add_argument("--materials", dest="catalog_materials", type=Path, metavar="FILE",
                   help="your material catalogue (TOML, [materials.NAME]), read before "
                   "configs/materials.toml: a name in it shadows the shipped one")  # fmt: skip

    def with_catalogs(a: argparse.Namespace) -> Any:
        from analysis.config import user_catalogs

        with user_catalogs(a.catalog_tools, a.catalog_materials):
            return run(a)

    p.set_defaults(func=with_catalogs)
