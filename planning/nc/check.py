"""A program file checked as ``cutlab nc check|motions|plot`` see it: interpreted (streamed, with a
progress callback by bytes for big files), its summary (lengths, times, bounding box, warnings)
and its motion table; and (``cutlab nc check --dialect``) what a controller would refuse in it
(:func:`dialect_problems`, :mod:`planning.nc.dialect`).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from planning.nc.dialect import DialectProblem, check_dialect
from planning.nc.interpreter import Interpreter
from planning.nc.motion import Motion
from planning.nc.run import file_lines
from planning.nc.stats import axis_limit_problems, motion_stats

if TYPE_CHECKING:
    from analysis.config import MachineConfig

#: files this big (bytes) or bigger report progress while they are interpreted
PROGRESS_MIN_BYTES = 2_000_000
_ROTARY_COLUMNS = ["a0", "b0", "c0", "a1", "b1", "c1"]


def progress_lines(
    path: str | Path, progress: Callable[[float, float], None] | None = None
) -> Iterator[str]:
    """The file's lines; for a file of :data:`PROGRESS_MIN_BYTES` or more, ``progress(bytes_done,
    bytes_total)`` is called every 20 000 lines and once at the end."""
    try:
        size_bytes = os.path.getsize(path)
    except OSError:
        size_bytes = 0
    if progress is None or size_bytes < PROGRESS_MIN_BYTES:
        yield from file_lines(path)
        return
    done_bytes = 0
    for i, raw in enumerate(file_lines(path)):
        done_bytes += len(raw)
        if i % 20_000 == 0:  # report rarely: the loop does ~200k lines/s
            progress(done_bytes, size_bytes)
        yield raw
    progress(size_bytes, size_bytes)


@dataclass(frozen=True)
class CheckedProgram:
    """An interpreted program file: its interpreter (warnings, blocks seen), motion and machine."""

    file: str
    interpreter: Interpreter
    motion: Motion
    machine: MachineConfig | None

    @property
    def warnings(self) -> list[str]:
        """The interpreter's warnings (lenient mode, G28 without a machine, ...)."""
        return [str(w) for w in self.interpreter.warnings]

    def summary(self) -> dict[str, Any]:
        """``cutlab nc check``'s result: blocks, motions, lengths (mm), times (s), bbox (mm),
        the rotary ranges (deg) of a program that turns an axis, and every warning (the
        interpreter's, then the machine's travel limits)."""
        motion, st = self.motion, motion_stats(self.motion, self.machine)
        limits = [f"{self.file}: {p}" for p in axis_limit_problems(motion, self.machine)]
        out: dict[str, Any] = {
            "file": self.file,
            "blocks": self.interpreter.blocks_seen,
            "motions": len(motion),
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
        if motion.has_rotary_travel.any() or any(st.rotary_min_deg) or any(st.rotary_max_deg):
            out["rotary_range_deg"] = {
                c: [st.rotary_min_deg[i], st.rotary_max_deg[i]] for i, c in enumerate("ABC")
            }
        return out

    def motion_table(self) -> Any:
        """One row per segment (a pandas DataFrame); a 3-axis program has no a0..c1 columns."""
        df = self.motion.to_dataframe()
        if not (self.motion.rotary_start_deg.any() or self.motion.rotary_end_deg.any()):
            df = df.drop(columns=_ROTARY_COLUMNS)
        return df


def check_program(
    path: str,
    machine: str | None = None,
    *,
    strict: bool = True,
    progress: Callable[[float, float], None] | None = None,
) -> CheckedProgram:
    """Interpret the program file ``path`` on ``machine`` (a config name or TOML path; None: no
    machine). ``strict`` False reports unknown codes as warnings; ``progress`` see
    :func:`progress_lines`. NC errors raise :class:`~planning.nc.errors.NCError`."""
    cfg = None
    if machine:
        from analysis.config import load_machine

        cfg = load_machine(machine)
    it = Interpreter(cfg, strict=strict, file=path)
    motion = it.run(progress_lines(path, progress))
    return CheckedProgram(path, it, motion, cfg)


def dialect_problems(path: str, dialect: str, *, strip: bool = True) -> list[DialectProblem]:
    """What the ``dialect`` controller (grbl, fanuc, linuxcnc) would refuse or run differently in
    the program file ``path``, with file:line:column (``strip``: GRBL lines as the streamer sends
    them, without comments, spaces and N words). NCError if the file cannot be read."""
    return check_dialect(list(file_lines(path)), dialect, file=str(path), strip=strip)
