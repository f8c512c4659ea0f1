"""Whole programs in, Motion out: text, Program, lines or a file (streamed), and the modal state
at block N for restarts. All build on :class:`~planning.nc.interpreter.Interpreter`.
"""

from __future__ import annotations

import itertools
import os
import re
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import IO, TYPE_CHECKING, TypedDict, Unpack

from planning.nc import _lexer
from planning.nc.errors import NCError
from planning.nc.interpreter import CHUNK_BLOCKS, Interpreter
from planning.nc.motion import Motion
from planning.nc.program import Program
from planning.nc.state import ModalState

if TYPE_CHECKING:
    from analysis.config import MachineConfig


class InterpreterOptions(TypedDict, total=False):
    """The :class:`~planning.nc.interpreter.Interpreter` options :func:`interpret` and the others
    pass on (machine, strict and file aside)."""

    dialect: str | None
    block_delete: bool
    arc_tolerance_mm: float | None
    work_offsets_mm: Mapping[int | float, Sequence[float]] | None
    peck_clearance_mm: float | None
    reference_mm: Sequence[float] | None
    second_reference_mm: Sequence[float] | None
    state: ModalState | None
    cutter_comp: str
    probing: str
    fast: bool


def _lines_of(source: str | os.PathLike[str] | Program | Iterable[str]) -> Iterable[str]:
    if isinstance(source, os.PathLike):
        return file_lines(source)
    if isinstance(source, str):
        return _lexer.split_lines(source)
    if isinstance(source, Program):
        return source.lines
    lines: Iterable[str] | None = getattr(source, "lines", None)  # a program-like object's
    return lines if lines is not None else source


def interpret(
    source: str | os.PathLike[str] | Program | Iterable[str],
    machine: MachineConfig | None = None,
    *,
    strict: bool = True,
    file: str | None = None,
    **options: Unpack[InterpreterOptions],
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


def iter_motion_chunks(
    source: str | os.PathLike[str] | Program | Iterable[str],
    machine: MachineConfig | None = None,
    *,
    strict: bool = True,
    file: str | None = None,
    chunk_blocks: int = CHUNK_BLOCKS,
    interpreter: Interpreter | None = None,
    **options: Unpack[InterpreterOptions],
) -> Iterator[Motion]:
    """Interpret a program as :func:`interpret` does, streaming: a generator of Motion chunks
    (one per ``chunk_blocks`` blocks, empty ones left out) whose concatenation is
    ``interpret(source, ...)``. A ``pathlib.Path`` is read in bounded chunks
    (:func:`file_lines`), so memory is bounded by the chunk, not the program.

    Give ``interpreter`` (built by the caller, e.g. to read its ``warnings`` and
    ``blocks_seen`` afterwards) instead of ``machine``/``strict``/``options``.
    """
    if interpreter is None:
        name = file or getattr(source, "file", None) or _path_name(source) or "<program>"
        interpreter = Interpreter(machine, strict=strict, file=name, **options)
    elif options:
        raise TypeError("give either an interpreter or interpreter options, not both")
    yield from interpreter.iter_chunks(_lines_of(source), chunk_blocks=chunk_blocks)


def _path_name(source: object) -> str | None:
    return os.fspath(source) if isinstance(source, os.PathLike) else None


#: longest line (characters, line end excluded) a program file may have. LinuxCNC's own limit
#: is 256 characters (LINELEN); this one is generous and only keeps a single-line 50 MB file
#: (a binary, a program without line ends) from being read into memory whole.
MAX_LINE_CHARS = 65_536
#: bytes read from a program file at a time
READ_BYTES = 1 << 20


def file_lines(
    path: str | os.PathLike[str], *, max_line_chars: int = MAX_LINE_CHARS
) -> Iterator[str]:
    """Lines of a program file, read lazily in bounded binary chunks (LF, CR LF or CR line ends;
    a UTF-8 BOM is dropped). LF-ended lines keep their ``"\n"``; memory stays bounded by
    :data:`READ_BYTES` plus one line.

    NCError names the line and column of bytes that are not UTF-8/ASCII text, a line longer
    than ``max_line_chars`` (as soon as it is seen, without reading the rest of it), or why the
    file cannot be read.
    """
    # a C-level chain over lists of lines: no generator frame per line
    return itertools.chain.from_iterable(file_line_lists(path, max_line_chars))


def file_line_lists(
    path: str | os.PathLike[str], max_line_chars: int = MAX_LINE_CHARS
) -> Iterator[list[str]]:
    """:func:`file_lines` a list of lines (one read) at a time; an error comes after the lines
    before it, as with :func:`file_lines`."""
    name = str(path)
    try:
        fh = open(path, "rb")
    except OSError as exc:
        raise NCError(f"cannot read the program: {exc.strerror}", file=name) from None
    with fh:
        yield from _chunked_lines(fh, name, max_line_chars)


def _too_long(name: str, line: int, limit: int) -> NCError:
    return NCError(
        f"line longer than {limit} characters (the limit for a block; is this a program file?)",
        file=name,
        line=line,
    )


#: what str.splitlines also splits an ASCII text at, besides "\n" and "\r"
_OTHER_BREAKS = ("\x0b", "\x0c", "\x1c", "\x1d", "\x1e")


def _chunked_lines(fh: IO[bytes], name: str, limit: int) -> Iterator[list[str]]:
    carry = b""
    n = 0  # lines yielded so far
    first = True
    split_cr = _lexer.split_lines
    while True:
        try:
            data = fh.read(READ_BYTES)
        except OSError as exc:
            raise NCError(f"cannot read the program: {exc.strerror}", file=name) from None
        if first and data:
            first = False
            if data.startswith(b"\xef\xbb\xbf"):
                data = data[3:]
        if not data:
            if not carry:
                return
            buf, carry = carry, b""
        else:
            buf = carry + data if carry else data
            cut = buf.rfind(b"\n") + 1
            if cut == 0:  # no LF: CR-only line ends, or one long line
                cut = buf.rfind(b"\r", 0, len(buf) - 1) + 1  # a final CR may precede an LF
            carry = buf[cut:]
            buf = buf[:cut]
            # bytes >= characters: 4 bytes per character at most in UTF-8
            if len(carry) > 4 * limit + 2:
                raise _too_long(name, n + 1 + buf.count(b"\n"), limit)
            if not buf:
                continue
        try:
            text = buf.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise _lexer.undecodable(name, buf, exc, n + 1) from None
        if text.isascii() and "\r" not in text and not any(c in text for c in _OTHER_BREAKS):
            out = text.splitlines(keepends=True)  # as below, split in C
        elif "\r" in text:
            lines = text.split("\n")
            last = lines.pop()
            out = []
            for raw in lines:
                if "\r" in raw and "\r" in raw.rstrip("\r"):  # CR-only line ends
                    out.extend(split_cr(raw))
                else:
                    out.append(raw + "\n")
            if last:
                out.extend(split_cr(last))
        else:
            lines = text.split("\n")
            last = lines.pop()
            out = [raw + "\n" for raw in lines]
            if last:
                out.append(last)
        if out and max(map(len, out)) > limit:
            for k, raw in enumerate(out):
                if len(raw) > limit and len(raw.rstrip("\r\n")) > limit:
                    if k:
                        yield out[:k]
                    raise _too_long(name, n + k + 1, limit)
        n += len(out)
        if out:
            yield out


def interpret_file(
    path: str | Path, machine: MachineConfig | None = None, *, strict: bool = True,
    **options: Unpack[InterpreterOptions],
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
    **options: Unpack[InterpreterOptions],
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


_COMMENT_B = re.compile(rb"\([^()\n\r]*\)|;[^\n\r]*")
_ROTARY_B = re.compile(rb"[ABCabc][ \t]*[-+.0-9]")


def file_mentions_rotary(path: str | Path) -> bool:
    """Whether the program file has an A, B or C word outside comments (a fast byte scan, in
    bounded chunks): the streamed motion table shows the a0..c1 columns only then. Conservative:
    True for a program whose A/B/C words never turn an axis."""
    try:
        with open(path, "rb") as fh:
            carry = b""
            while data := fh.read(READ_BYTES):
                buf = carry + data
                cut = max(buf.rfind(b"\n"), buf.rfind(b"\r")) + 1
                carry = buf[cut:][-4 * MAX_LINE_CHARS :]
                if _ROTARY_B.search(_COMMENT_B.sub(b" ", buf[:cut])):
                    return True
            return bool(_ROTARY_B.search(_COMMENT_B.sub(b" ", carry)))
    except OSError as exc:
        raise NCError(f"cannot read the program: {exc.strerror}", file=str(path)) from None
