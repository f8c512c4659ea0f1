"""Whole programs in, Motion out: text, Program, lines or a file (streamed), and the modal state
at block N for restarts. All build on :class:`~planning.nc.interpreter.Interpreter`.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from planning.nc import _lexer
from planning.nc.errors import NCError
from planning.nc.interpreter import Interpreter
from planning.nc.motion import Motion
from planning.nc.state import ModalState

if TYPE_CHECKING:
    from analysis.config import MachineConfig
    from planning.nc.program import Program


def _lines_of(source: str | os.PathLike | Program | Iterable[str]) -> Iterable[str]:
    if isinstance(source, os.PathLike):
        return file_lines(source)
    if isinstance(source, str):
        return _lexer.split_lines(source)
    lines = getattr(source, "lines", None)
    return lines if lines is not None else source


def interpret(
    source: str | os.PathLike | Program | Iterable[str],
    machine: MachineConfig | None = None,
    *,
    strict: bool = True,
    file: str | None = None,
    **options,
) -> Motion:
    """Interpret a whole program to Motion: program text (a ``str`` is text, not a file name), a
    ``pathlib.Path`` (streamed), a :class:`~planning.nc.Program`, or an iterable of lines.

    ``options`` go to :class:`Interpreter` (dialect, block_delete, arc_tolerance_mm,
    work_offsets_mm, peck_clearance_mm, state). Use :class:`Interpreter` directly to get the
    warnings of lenient mode and the final state.
    """
    name = file or getattr(source, "file", None) or _path_name(source) or "<program>"
    it = Interpreter(machine, strict=strict, file=name, **options)
    return it.run(_lines_of(source))


def _path_name(source: object) -> str | None:
    return os.fspath(source) if isinstance(source, os.PathLike) else None


def file_lines(path: str | Path) -> Iterator[str]:
    """Lines of a program file, read lazily (LF, CR LF or CR line ends; a UTF-8 BOM is dropped).

    NCError names the line and column of bytes that are not UTF-8/ASCII text, or why the file
    cannot be read.
    """
    try:
        with open(path, "rb") as fh:
            for n, data in enumerate(fh, 1):
                try:
                    raw = data.decode("utf-8")
                except UnicodeDecodeError as exc:
                    raise _lexer.undecodable(str(path), data, exc, n) from None
                if n == 1 and raw.startswith("\ufeff"):
                    raw = raw[1:]
                if "\r" in raw and "\r" in raw.rstrip("\r\n"):  # CR-only line ends
                    yield from _lexer.split_lines(raw)
                else:
                    yield raw
    except OSError as exc:
        raise NCError(f"cannot read the program: {exc.strerror}", file=str(path)) from None


def interpret_file(
    path: str | Path, machine: MachineConfig | None = None, *, strict: bool = True, **options
) -> Motion:
    """Interpret a program file, streaming it line by line (memory: the segment arrays only)."""
    return interpret(Path(path), machine, strict=strict, file=str(path), **options)


def state_at_block(
    source: str | Program | Iterable[str],
    block: int,
    machine: MachineConfig | None = None,
    *,
    strict: bool = True,
    file: str | None = None,
    **options,
) -> ModalState:
    """The modal state in force just before block ``block`` (0-based) executes.

    This is what a restart from block N must re-establish (units, plane, distance mode, work
    offset, tool, spindle, coolant, feed, position); see
    :func:`planning.nc.restart.restart_preamble`.
    """
    if block < 0:
        raise NCError(f"block index must be >= 0, got {block}", file=file or "<program>")
    name = file or getattr(source, "file", None) or _path_name(source) or "<program>"
    it = Interpreter(machine, strict=strict, file=name, **options)
    it.skip(itertools.islice(_lines_of(source), block))
    if it.blocks_seen < block:
        raise NCError(
            f"block {block} is past the end of the program: its blocks are 0..{it.blocks_seen - 1}"
            " (block i is line i + 1)",
            file=name,
        )
    return it.state
