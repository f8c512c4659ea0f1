"""A program file checked as ``cutlab nc check|motions|plot`` see it: interpreted (streamed in
chunks, with a progress callback by bytes for big files), its summary (lengths, times, bounding
box, warnings) accumulated chunk by chunk so memory is bounded by the chunk, not the program, and
its motion table (streamed to CSV); and (``cutlab nc check --dialect``) what a controller would
refuse in it (:func:`dialect_problems`, :mod:`planning.nc.dialect`).
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, NotRequired, TextIO, TypedDict

from planning.nc.interpreter import Interpreter
from planning.nc.motion import Motion
from planning.nc.run import file_line_lists, file_lines, file_mentions_rotary
from planning.nc.stats import MotionStats, StreamStats, axis_limit_problems

if TYPE_CHECKING:
    import pandas as pd

    from analysis.config import MachineConfig
    from planning.nc.dialect import DialectProblem

#: files this big (bytes) or bigger report progress while they are interpreted
PROGRESS_MIN_BYTES = 2_000_000
_ROTARY_COLUMNS = ["a0", "b0", "c0", "a1", "b1", "c1"]


def progress_lines(
    path: str | Path, progress: Callable[[float, float], None] | None = None
) -> Iterator[str]:
    """The file's lines; for a file of :data:`PROGRESS_MIN_BYTES` or more, ``progress(bytes_done,
    bytes_total)`` is called after each read (about a MB) and once at the end."""
    try:
        size_bytes = os.path.getsize(path)
    except OSError:
        size_bytes = 0
    if progress is None or size_bytes < PROGRESS_MIN_BYTES:
        return file_lines(path)
    return itertools.chain.from_iterable(_reporting(file_line_lists(path), size_bytes, progress))


def _reporting(
    lists: Iterator[list[str]], size_bytes: int, progress: Callable[[float, float], None]
) -> Iterator[list[str]]:
    done_bytes = 0
    for lines in lists:
        done_bytes += sum(map(len, lines))  # characters: bytes for the ASCII of a program
        progress(min(done_bytes, size_bytes), size_bytes)
        yield lines
    progress(size_bytes, size_bytes)


_AXES = "XYZABC"


class ProgramSummary(TypedDict):
    """:meth:`CheckedProgram.summary`: `cutlab nc check`'s result (mm, s, mm/min, deg)."""

    file: str
    blocks: int
    motions: int
    cutting_length_mm: float
    rapid_length_mm: float
    time_s: float
    time_with_accel_s: float | None
    feed_time_s: float
    rapid_time_s: float
    dwell_s: float
    rapid_mm_min: float
    bbox: dict[str, list[float]]
    warnings: list[str]
    rotary_range_deg: NotRequired[dict[str, list[float]]]
    dialect: NotRequired[str]
    dialect_problems: NotRequired[list[dict[str, object]]]


@dataclass(frozen=True)
class CheckedProgram:
    """An interpreted program file: its interpreter (warnings, blocks seen), its statistics and
    travel-limit problems, the machine, and its motion (None when only checked)."""

    file: str
    interpreter: Interpreter
    stats: MotionStats
    limits: list[str]
    rotary: bool
    machine: MachineConfig | None
    motion: Motion | None = None

    @property
    def warnings(self) -> list[str]:
        """The interpreter's warnings (lenient mode, G28 without a machine, ...)."""
        return [str(w) for w in self.interpreter.warnings]

    def summary(self) -> ProgramSummary:
        """``cutlab nc check``'s result: blocks, motions, lengths (mm), times (s), bbox (mm),
        the rotary ranges (deg) of a program that turns an axis, and every warning (the
        interpreter's, then the machine's travel limits)."""
        st = self.stats
        limits = [f"{self.file}: {p}" for p in self.limits]
        out: ProgramSummary = {
            "file": self.file,
            "blocks": self.interpreter.blocks_seen,
            "motions": st.segments,
            "cutting_length_mm": st.cutting_length_mm,
            "rapid_length_mm": st.rapid_length_mm,
            "time_s": st.time_s,
            "time_with_accel_s": st.accel_time_s,
            "feed_time_s": st.feed_time_s,
            "rapid_time_s": st.rapid_time_s,
            "dwell_s": st.dwell_s,
            "rapid_mm_min": st.rapid_mm_min,
            "bbox": {"min_mm": list(st.bbox_min_mm), "max_mm": list(st.bbox_max_mm)},
            "warnings": self.warnings + limits,
        }
        if self.rotary or any(st.rotary_min_deg) or any(st.rotary_max_deg):
            out["rotary_range_deg"] = {
                c: [st.rotary_min_deg[i], st.rotary_max_deg[i]] for i, c in enumerate("ABC")
            }
        return out

    def motion_table(self) -> pd.DataFrame:
        """One row per segment (a pandas DataFrame; needs the kept motion); a 3-axis program has
        no a0..c1 columns."""
        motion = self.motion
        if motion is None:
            raise ValueError(f"{self.file}: no motion kept (check_program(keep_motion=True))")
        df = motion.to_dataframe()
        if not (motion.rotary_start_deg.any() or motion.rotary_end_deg.any()):
            df = df.drop(columns=_ROTARY_COLUMNS)
        return df


def check_program(
    path: str,
    machine: str | None = None,
    *,
    strict: bool = True,
    progress: Callable[[float, float], None] | None = None,
    keep_motion: bool = False,
    dialect: str | None = None,
) -> CheckedProgram:
    """Interpret the program file ``path`` on ``machine`` (a config name or TOML path; None: no
    machine), chunk by chunk, as ``dialect``'s controller does (default the machine's, else
    Fanuc; a machine given keeps its own). ``strict`` False reports unknown codes as warnings;
    ``progress`` see :func:`progress_lines`; ``keep_motion`` keeps the whole motion (for a plot
    or a table). NC errors raise :class:`~planning.nc.errors.NCError`."""
    cfg = _machine(machine)
    it = Interpreter(cfg, strict=strict, file=path, dialect=_dialect(cfg, dialect))
    acc, rotary, kept = StreamStats(cfg), False, []
    first_limit: dict[str, str] = {}
    for part in it.iter_chunks(progress_lines(path, progress)):
        acc.add(part)
        rotary |= bool(part.has_rotary_travel.any())
        for problem in axis_limit_problems(part, cfg):  # "line N: X goes to ...": first per axis
            first_limit.setdefault(problem.split()[2], problem)
        if keep_motion:
            kept.append(part)
    limits = [first_limit[a] for a in _AXES if a in first_limit]
    motion = (Motion.concatenate(kept) if kept else Motion.empty()) if keep_motion else None
    return CheckedProgram(path, it, acc.result(), limits, rotary, cfg, motion)


def write_motions_csv(
    path: str,
    out: str | Path | TextIO,
    machine: str | None = None,
    *,
    strict: bool = True,
    progress: Callable[[float, float], None] | None = None,
    dialect: str | None = None,
) -> Interpreter:
    """``cutlab nc motions --csv``: one row per segment of the program file ``path`` written to
    ``out`` (a stream, or a file path: written whole or not at all) as it is interpreted (bounded
    memory; floats that read back unchanged); the a0..c1 columns when the file has A/B/C words.
    ``dialect`` as in :func:`check_program`. Returns the interpreter (its warnings)."""
    from planning.nc.table import write_motion_csv  # here: `nc check` needs no CSV writer

    cfg = _machine(machine)
    it = Interpreter(cfg, strict=strict, file=path, dialect=_dialect(cfg, dialect))
    rotary = file_mentions_rotary(path)
    if not isinstance(out, str | Path):
        write_motion_csv(it.iter_chunks(progress_lines(path, progress)), out, rotary=rotary)
        return it
    target = Path(out)
    part = target.with_name(target.name + ".part")
    try:
        with open(part, "w", newline="") as fh:
            write_motion_csv(it.iter_chunks(progress_lines(path, progress)), fh, rotary=rotary)
        part.replace(target)
    finally:
        part.unlink(missing_ok=True)
    return it


def _dialect(cfg: MachineConfig | None, dialect: str | None) -> str | None:
    """The dialect to interpret in: a machine's own (its file says how its control reads a
    program; ``--dialect`` beside it only lists what another control would refuse), else
    ``dialect``."""
    return cfg.dialect if cfg is not None else dialect


def _machine(machine: str | None) -> MachineConfig | None:
    if not machine:
        return None
    from analysis.config import load_machine

    return load_machine(machine)


def dialect_problems(path: str, dialect: str, *, strip: bool = True) -> list[DialectProblem]:
    """What the ``dialect`` controller (grbl, fanuc, linuxcnc) would refuse or run differently in
    the program file ``path``, with file:line:column (``strip``: GRBL lines as the streamer sends
    them, without comments, spaces and N words). NCError if the file cannot be read."""
    from planning.nc.dialect import check_dialect  # here: only `nc check --dialect` needs it

    return check_dialect(list(file_lines(path)), dialect, file=str(path), strip=strip)
