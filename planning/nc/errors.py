"""Errors and warnings of the NC language.

Every problem in a program is reported with its place, ``file:line:column``, the offending word and
why, e.g.::

    part.nc:12:15: 'R4': arc radius 4 mm is smaller than half the chord (6.5 mm)

:class:`NCError` is raised (strict and lenient modes alike) for anything that makes the motion
unknowable; :class:`NCWarning` records what lenient mode skipped (unknown codes, unused words) so
nothing is dropped silently.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from planning.errors import PlanningError


def _where(file: str, line: int, column: int, word: str, reason: str) -> str:
    head = f"{file}:{line}:{column}" if line else file  # line 0: about the whole file
    return f"{head}: {word!r}: {reason}" if word else f"{head}: {reason}"


class NCError(PlanningError):
    """A program cannot be read or interpreted.

    Attributes
    ----------
    file : str
        Program file name (``"<program>"`` for text without a file).
    line : int
        1-based source line (0 when unknown).
    column : int
        1-based column of the offending word (1 when the whole block is at fault).
    word : str
        The offending word as written (``""`` when not about one word).
    reason : str
        Why, with the numbers and the expected unit or range.
    """

    def __init__(
        self,
        reason: str,
        *,
        file: str = "<program>",
        line: int = 0,
        column: int = 1,
        word: str = "",
    ) -> None:
        self.file = file
        self.line = line
        self.column = column
        self.word = word
        self.reason = reason
        super().__init__(_where(file, line, column, word, reason))

    def __reduce__(  # keep keyword-only fields through pickling (multiprocessing)
        self,
    ) -> tuple[Callable[..., NCError], tuple[str, str, int, int, str]]:
        return (_rebuild, (self.reason, self.file, self.line, self.column, self.word))


def _rebuild(reason: str, file: str, line: int, column: int, word: str) -> NCError:
    return NCError(reason, file=file, line=line, column=column, word=word)


@dataclass(frozen=True)
class NCWarning:
    """Something lenient mode skipped or an oddity worth knowing; same fields as NCError."""

    reason: str
    file: str = "<program>"
    line: int = 0
    column: int = 1
    word: str = ""

    def __str__(self) -> str:
        return _where(self.file, self.line, self.column, self.word, self.reason)
