"""A program as the streamer sends it: its blocks (index, source line, text).

``load_program`` reads a file, checks that every character can be sent (printable 7-bit ASCII, as
ISO code needs) and, through ``planning.nc``, that the program is valid NC, so an NC error is
reported with file:line:column before anything is sent.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass
from pathlib import Path

from rig.dnc.errors import DncError


@dataclass(frozen=True)
class Block:
    """index : 0-based block index (as ``planning.nc`` counts it); line : 1-based source line."""

    index: int
    line: int
    text: str


@dataclass(frozen=True)
class Program:
    """name : file name or label; text : the whole source; blocks : what is streamed."""

    name: str
    text: str
    blocks: tuple[Block, ...]

    def __len__(self) -> int:
        return len(self.blocks)

    def position_of(self, block: int) -> int:
        """Position in :attr:`blocks` of the first block with index >= ``block``."""
        return bisect.bisect_left(self.blocks, block, key=lambda b: b.index)


def _check_chars(text: str, name: str) -> None:
    for lineno, line in enumerate(text.splitlines(), 1):
        for col, ch in enumerate(line, 1):
            if not (" " <= ch <= "~" or ch == "\t"):
                raise DncError(
                    f"{name}:{lineno}:{col}: character {ch!r} cannot be sent over the DNC link "
                    "(printable 7-bit ASCII expected)"
                )


def split_blocks(text: str) -> tuple[Block, ...]:
    """The blocks to send: every line but blank lines and ``%`` tape marks (the streamer frames
    the program itself). As in ``planning.nc``, block ``i`` is source line ``i + 1``, so the
    indices of the blocks sent skip the lines left out."""
    out = []
    for lineno, raw in enumerate(text.splitlines(), 1):
        s = raw.strip()
        if not s or s == "%":
            continue
        out.append(Block(lineno - 1, lineno, s))
    return tuple(out)


def program_from_text(text: str, name: str = "<program>", check_nc: bool = True) -> Program:
    """A :class:`Program` from NC text; with ``check_nc`` the whole program is interpreted first
    and an NC error becomes a :class:`DncError` naming file:line:column (nothing is sent)."""
    _check_chars(text, name)
    if check_nc:
        from rig.dnc.nc import check_program

        check_program(text, name)
    return Program(name, text, split_blocks(text))


def load_program(path: str | Path, check_nc: bool = True) -> Program:
    p = Path(path)
    try:
        text = p.read_text(encoding="ascii")
    except FileNotFoundError:
        raise DncError(f"{p}: program file not found") from None
    except UnicodeDecodeError as exc:
        raise DncError(
            f"{p}: byte {exc.start}: not 7-bit ASCII; the DNC link sends ISO code only"
        ) from None
    except OSError as exc:
        raise DncError(f"{p}: cannot read the program: {exc}") from None
    program = program_from_text(text, str(p), check_nc)
    if len(program) == 0:
        raise DncError(f"{p}: the program has no blocks to send")
    return program
