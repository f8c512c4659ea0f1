"""Every command in README.md, run as typed (issue 32, item 3).

The commands are read from the README when the tests are collected (fenced and indented code
blocks, and inline `cutlab ...` spans), so a command added to the README is tested without
touching this file. Each is one case, named by its README line. They run in README order in one
scratch folder holding a copy of the shipped `data/` (and `configs`, `bench`, `.venv` linked), so
a command that uses what an earlier one wrote (a campaign before its report, `rules derive`
before `rules add`) finds it. A case passes when the command exits 0 (or the exit status the
README gives it, e.g. `plan check` exits 4 on the demo part) and prints no traceback.

Not every README line is a command to run:
- a synopsis (`cutlab plan check PROGRAM --tool T ...`: an upper-case placeholder or `...`) is
  not run; optional parts in brackets (`[--json]`) are left out of a command that is otherwise
  concrete, as a reader would;
- a line of :data:`SKIP` (hardware, a server, an installer, the test suite itself) is skipped
  with its reason;
- a line of :data:`SLOW` (a full campaign, 5-axis orientation, benchmarks) and every command that
  needs one (:data:`NEEDS`) run only with ``-m slow``.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest

#: the commands build on each other in one scratch folder and take seconds each: all in `long`
pytestmark = pytest.mark.long

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"

#: what a command line starts with
_COMMAND = re.compile(r"^(cutlab|\.venv/bin/\S+|python3?|cd|\.ci/run|pytest)(\s|$)")
#: an argument that stands for something the reader fills in (FILE, IN.nc, KEY=VALUE, T, OUT/x.nc,
#: ...)
_PLACEHOLDER = re.compile(
    r"^(-[-\w]+=)?[A-Z][A-Z0-9_]*(\.[a-z0-9]+)?(=[A-Z]+)?$|^[A-Z][A-Z0-9_]*/|\.\.\.|\|"
)

#: (pattern searched in the command, reason): not run here
SKIP: list[tuple[str, str]] = [
    (r"^python3 -m venv", "installs the package (network); the test environment is that install"),
    (r"-m pytest|^pytest", "the test suite itself"),
    (r"^\.ci/run", "installs Debian packages and runs the whole suite"),
    (r"/dev/ttyUSB|--protocol \S+ --machine|dnc (unlock|reset)", "needs a real serial port"),
    (r"^cutlab daq record (?!.*--sim)", "needs the NI DAQ device of configs/rig.toml"),
    (r"my(\.toml|-campaign\.toml)", "the reader's own campaign file (real-hardware procedure)"),
    (r"tcp://sched:", "needs a dask.distributed scheduler at sched:8786"),
    (r"--live|^cutlab console", "serves the console until stopped (tests/test_console*.py)"),
    (r"dnc serve", "answers a control's requests on a serial port until stopped"),
    (r"bench_catalog\.py", "writes 10 030 run files (13 GB) to measure the catalogue"),
]
#: long commands, run with -m slow only
SLOW: list[str] = [
    r"^cutlab demo",
    r"^cutlab campaign run (?!\S+ --dry-run)",
    r"^cutlab plan orient",
    r"^\.venv/bin/python bench/",
    r"^cutlab plan rough (configs/parts/)?seed000-bump",
]
#: (pattern, pattern of the command it needs): run only where that one runs
NEEDS: list[tuple[str, str]] = [
    (r"out/demo|--catalog|^cutlab catalog", r"^cutlab demo"),
    (r"campaign (status|report) feed-sweep|feed-sweep/runs", r"^cutlab campaign run feed-sweep$"),
    (r"program\.nc --machine mill-5axis", r"^cutlab plan orient configs/orient/impeller"),
    (r"campaign (status|report) stability-sweep", r"^cutlab campaign run stability-sweep"),
    (r"^cutlab rules (list|show|export|lookup)|--rules gm241-phi30", r"^cutlab rules add"),
    (r"gm241-phi30", r"^cutlab rules derive"),
]
#: (pattern, exit status the README documents for it)
EXIT: list[tuple[str, int]] = [
    (r"^cutlab plan check .*--tool T1=phi10-flat,T2=phi5-drill", 4),
    (r"^cutlab plan rough (configs/parts/)?seed000-bump", 3),  # written, 341 violations
]
#: (pattern, why): commands that fail as typed today, for a reason named here (strict: a fix
#: that makes one pass fails the case until its line is removed)
KNOWN_BROKEN: list[tuple[str, str]] = []
#: seconds a command may take (the slowest shipped campaign is a few minutes)
TIMEOUT_S = 900


@dataclass
class Command:
    line: int  # README line where it starts
    section: str
    typed: str  # as in the README (continuations joined)
    run: str = ""  # what runs: optional [..] parts left out
    block: int = -1  # code block number (-1: inline)
    cwd: str = ""  # from a `cd` earlier in the same block
    background: bool = False  # ends in `&`
    example_output: str = ""  # "# prints e.g. /dev/pts/4"
    synopsis: bool = False
    marks: list[str] = field(default_factory=list)

    @property
    def id(self) -> str:
        short = re.sub(r"\s+", " ", self.typed)[:70]
        return f"L{self.line}: {short}"


def _strip_optional(text: str) -> str:
    """`cutlab data info out/run.h5 [--json]` -> `cutlab data info out/run.h5`."""
    prev = None
    while prev != text:
        prev, text = text, re.sub(r"\s+\[[^\[\]]*\]", "", text)
    return text


def _is_synopsis(text: str) -> bool:
    try:
        words = shlex.split(text.split(" #")[0])
    except ValueError:
        return True
    return any(_PLACEHOLDER.search(w) for w in words[1:] if not w.startswith("'"))


def extract(text: str) -> list[Command]:
    """The README's commands in order (see the module docstring)."""
    out: list[Command] = []
    section, fenced, block, prev_blank, cwd = "", False, 0, True, ""
    lines = text.splitlines()
    i = 0
    in_indented = False
    while i < len(lines):
        raw = lines[i]
        n = i + 1
        i += 1
        stripped = raw.strip()
        if raw.startswith("#") and not fenced:
            section = raw.lstrip("#").strip()
            cwd = ""  # a reader's `cd` holds until the next section
            prev_blank, in_indented = False, False
            continue
        if stripped.startswith("```"):
            fenced = not fenced
            block += 1
            continue
        indent = len(raw) - len(raw.lstrip(" "))
        code = fenced or (indent >= 4 and (prev_blank or in_indented) and stripped != "")
        if not code:
            in_indented, prev_blank = False, stripped == ""
            if stripped and indent == 0 and not re.match(r"\d+\. ", stripped):
                cwd = ""  # ... or the next paragraph that is not a step of the same list
            for m in re.finditer(r"`(cutlab [^`]+)`", raw):
                out.append(Command(n, section, m.group(1)))
            continue
        if not fenced and not in_indented:  # an indented block begins
            block += 1
        in_indented, prev_blank = not fenced, False
        cmd = stripped
        while cmd.endswith("\\") and i < len(lines):
            cmd = cmd[:-1].rstrip() + " " + lines[i].strip()
            i += 1
        if not _COMMAND.match(cmd):
            continue
        if cmd.startswith("cd "):
            cwd = str(Path(cwd) / cmd.split()[1])
            continue
        out.append(Command(n, section, cmd, block=block, cwd=cwd))
    for c in out:
        body, _, comment = c.typed.partition(" #")
        body = body.strip()
        c.background = body.endswith("&")
        body = body.rstrip("&").strip()
        m = re.search(r"prints e\.g\. (\S+)", comment)
        c.example_output = m.group(1) if m else ""
        c.run = _strip_optional(body)
        c.synopsis = _is_synopsis(c.run)
        if c.block == -1 and not c.synopsis and not _inline_call(c.run):
            c.synopsis = True  # an inline mention of a command (`cutlab rules add`), not a call
    return out


def _inline_call(text: str) -> bool:
    """Whether an inline span is a call: it names a file (a word with / or a suffix) and
    cutlab's own parser takes it (`cutlab rules add` only names a command)."""
    words = shlex.split(text)[1:]
    if not any(re.search(r"/|\.\w+$", w) for w in words if not w.startswith("-")):
        return False
    import contextlib
    import io

    from rig.cli import build_parser

    try:
        with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
            build_parser().parse_args(shlex.split(text)[1:])
    except SystemExit:
        return False
    return True


def _first(patterns: list[tuple[str, object]], text: str) -> object | None:
    return next((v for p, v in patterns if re.search(p, text)), None)


def _cases() -> list[Command]:
    seen: set[str] = set()
    out = []
    for c in extract(README.read_text()):
        if c.synopsis or (c.run, c.cwd) in seen:
            continue
        seen.add((c.run, c.cwd))  # type: ignore[arg-type]
        out.append(c)
    return out


CASES = _cases()


def _slow(c: Command, seen: list[Command]) -> bool:
    if any(re.search(p, c.run) for p in SLOW):
        return True
    need = _first(NEEDS, c.run)  # type: ignore[arg-type]
    if need is None:
        return False
    return any(re.search(need, d.run) and _slow(d, []) for d in seen) or not any(
        re.search(need, d.run)
        for d in seen  # nothing earlier makes it: let the case say so
    )


def _params() -> list[object]:
    params = []
    for k, c in enumerate(CASES):
        marks = []
        why = _first(SKIP, c.run)
        broken = _first(KNOWN_BROKEN, c.run)  # type: ignore[arg-type]
        if why:
            marks.append(pytest.mark.skip(reason=str(why)))
        elif broken:
            marks.append(pytest.mark.xfail(reason=str(broken), strict=True))
        elif _slow(c, CASES[:k]):
            # the command and what it needs (the demo: minutes on a loaded machine) each within
            # TIMEOUT_S; pytest's default of 300 s would cut them short
            marks += [pytest.mark.slow, pytest.mark.timeout(2 * TIMEOUT_S + 60)]
        params.append(pytest.param(k, id=c.id, marks=marks))
    return params


class Scratch:
    """The scratch folder and what ran in it, in README order."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        shutil.copytree(ROOT / "data", folder / "data", ignore=shutil.ignore_patterns("*.sqlite"))
        for name in ("configs", "bench", ".venv", "tests"):
            (folder / name).symlink_to(ROOT / name)
        self.env = dict(os.environ, CUTLAB_RULEBASE=str(folder / "data" / "rulebase.sqlite"),
                        PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}",
                        MPLBACKEND="Agg", PYTHONDONTWRITEBYTECODE="1")  # fmt: skip
        self.done: dict[int, subprocess.CompletedProcess[str] | None] = {}
        self.background: dict[int, tuple[subprocess.Popen[str], str]] = {}

    def run(self, k: int) -> subprocess.CompletedProcess[str] | None:
        c = CASES[k]
        text = c.run
        for j, (_, printed) in self.background.items():  # "prints e.g. /dev/pts/4"
            if CASES[j].block == c.block and CASES[j].example_output:
                text = text.replace(CASES[j].example_output, printed)
        cwd = self.folder / c.cwd
        if c.background:
            return self._start(k, text, cwd)
        p = subprocess.run(["bash", "-c", text], cwd=cwd, env=self.env, capture_output=True,
                           text=True, timeout=TIMEOUT_S)  # fmt: skip
        self.done[k] = p
        return p

    def _start(self, k: int, text: str, cwd: Path) -> None:
        p = subprocess.Popen(["bash", "-c", f"exec {text}"], cwd=cwd, env=self.env, text=True,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             start_new_session=True)  # fmt: skip
        assert p.stdout is not None
        deadline = time.monotonic() + 30
        import selectors

        sel = selectors.DefaultSelector()
        sel.register(p.stdout, selectors.EVENT_READ)
        line = ""
        while not line and time.monotonic() < deadline and p.poll() is None:
            if sel.select(timeout=1.0):
                line = p.stdout.readline().strip()
        sel.close()
        assert line, f"{text}: printed nothing within 30 s (exit {p.poll()})"
        self.background[k] = (p, line.split()[-1])
        self.done[k] = None

    def stop_background(self) -> None:
        for p, _ in self.background.values():
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGTERM)
                try:
                    p.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    os.killpg(p.pid, signal.SIGKILL)
                    p.wait(timeout=10)
            for s in (p.stdout, p.stderr):
                if s is not None:
                    s.close()
        self.background.clear()


@pytest.fixture(scope="module")
def scratch(tmp_path_factory: pytest.TempPathFactory):  # noqa: ANN201
    s = Scratch(tmp_path_factory.mktemp("readme"))
    yield s
    s.stop_background()


@pytest.mark.parametrize("k", _params())
def test_readme_command(k: int, scratch: Scratch) -> None:
    c = CASES[k]
    need = _first(NEEDS, c.run)  # type: ignore[arg-type]
    if need is not None:  # made first if it has not run (a case selected alone, or out of order)
        j = next((j for j, d in enumerate(CASES) if re.search(str(need), d.run)), None)
        assert j is not None, f"README.md:{c.line}: nothing in the README matches {need!r}"
        if j not in scratch.done:
            p = scratch.run(j)
            assert p is not None and p.returncode == 0, (
                f"{CASES[j].typed}: {p and p.stderr[-2000:]}"
            )
    for j in range(k):  # a background command of this block, e.g. the simulated controller
        if CASES[j].background and CASES[j].block == c.block and j not in scratch.background:
            scratch.run(j)
    p = scratch.run(k)
    if c.background:
        return
    if k + 1 == len(CASES) or CASES[k + 1].block != c.block:
        scratch.stop_background()
    assert p is not None
    expected = _first(EXIT, c.run)
    expected = 0 if expected is None else expected
    where = f"README.md:{c.line} ({c.section}): {c.typed}"
    tail = f"\nstdout:\n{p.stdout[-3000:]}\nstderr:\n{p.stderr[-3000:]}"
    assert "Traceback (most recent call last)" not in p.stderr, where + tail
    assert p.returncode == expected, f"{where}: exit {p.returncode}, expected {expected}{tail}"


#: (section title pattern, why): sections whose every command is long or reads what a long one
#: wrote; they run with -m slow only
SLOW_ONLY_SECTIONS: list[tuple[str, str]] = [
    (r"^The demo", "the demo is a 23-cut campaign with its identification"),
    (r"^Stability sweep", "an 18-cut campaign and its report"),
    (r"^Feed rules", "the rules are derived from the feed-sweep campaign's runs"),
    (r"^Z-level roughing", "plan rough of seed 000's part: about 25 s of CPU"),
    (r"^5-axis", "plan orient: tens of seconds per model"),
    (r"^The run catalogue", "it indexes and fits the demo's runs"),
]


def test_the_readme_has_commands_and_every_section_runs_some_by_default() -> None:
    """The extraction finds the README's commands, and the default tier runs at least one in
    every section that has a command to run, except the sections of :data:`SLOW_ONLY_SECTIONS`
    (and a section listed there has no command the default tier runs: the list stays true)."""
    assert len(CASES) >= 40
    by_section: dict[str, list[bool]] = {}
    for k, c in enumerate(CASES):
        if _first(SKIP, c.run) is not None or _first(KNOWN_BROKEN, c.run) is not None:
            continue
        by_section.setdefault(c.section, []).append(not _slow(c, CASES[:k]))
    slow_only = {s for s, d in by_section.items() if not any(d)}
    listed = {s for s in by_section if _first(SLOW_ONLY_SECTIONS, s) is not None}  # type: ignore[arg-type]
    assert slow_only - listed == set(), "sections the default tier does not run"
    assert listed - slow_only == set(), "listed as slow-only but run by default: drop the line"
