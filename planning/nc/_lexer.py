"""Splitting one block's text into words (private).

Two paths that accept exactly the same language:

* :func:`block_words` — the hot path: comments removed by one regex, the rest upper-cased, checked
  by one ``fullmatch`` and split by one ``findall`` into ``(letter, number_text)`` pairs. No column
  bookkeeping: errors are rare, so the error path re-reads the line.
* :func:`tokenize` — the layout-keeping path used by the editor and for error columns: every
  character of the line belongs to exactly one :class:`Token` (space, word, comment, block delete,
  percent), so joining the tokens' text gives the line back byte for byte.

Language: words are a letter (either case) followed by a signed decimal number, spaces allowed
between words and between letter and number (``g1x10y-2.5f300``, ``G01 X 10.``); comments are
``( ... )`` (not nested, closed on the same line) or ``;`` to the end of the line; ``/`` (optionally
``/1``..``/9``) as the first thing on a line marks block delete; a line holding ``%`` (and at most
comments) is the tape start/end mark. Only ASCII outside comments.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import TypedDict

from planning.nc.errors import NCError

MAX_INT_DIGITS = 12  # keeps every number finite and every G/M/T integer exact
NUMBER = r"[-+]?(?:[0-9]{1,12}(?:\.[0-9]*)?|\.[0-9]+)"
WS = "[ \t\r\n\f\v]"
_WS_CHARS = " \t\r\n\f\v"
_WORD_RE = re.compile(r"([A-Z])" + WS + "*(" + NUMBER + ")")
_BLOCK_OK = re.compile(WS + "*(?:[A-Z]" + WS + "*" + NUMBER + WS + "*)*")
# comments become a NUL: it separates words but, unlike a space, not a letter from its number
_CUT = "\x00"
_BLOCK_OK_CUT = re.compile(
    "[ \t\r\n\f\v\x00]*(?:[A-Z]" + WS + "*" + NUMBER + "[ \t\r\n\f\v\x00]*)*"
)
_COMMENT_RE = re.compile(r"\([^()]*\)|;.*", re.DOTALL)  # as _TOKEN_RE: ";" runs to the end
_TOKEN_RE = re.compile(
    r"(?P<space>" + WS + "+)"
    r"|(?P<comment>\([^()]*\)|;.*)"
    r"|(?P<word>([A-Za-z])" + WS + "*(" + NUMBER + "))"
    r"|(?P<delete>/[1-9]?)"
    r"|(?P<percent>%)"
    r"|(?P<bad>\([^)]*\(|\(.*|.)",
    re.DOTALL,
)

_NEWLINE_RE = re.compile(r"\r\n|\r|\n")
Words = list[tuple[str, str]]
_EMPTY: Words = []


@dataclass(frozen=True, slots=True)
class Token:
    """A piece of a line: ``kind`` is space, word, comment, delete, percent or bad.

    For words, ``letter`` is upper-case and ``number`` the number text as written.
    ``column`` is 1-based.
    """

    kind: str
    text: str
    column: int
    letter: str = ""
    number: str = ""


def tokenize(raw: str) -> list[Token]:
    """All tokens of one line, in order; ``"".join(t.text for t in tokens) == raw``."""
    out = []
    for m in _TOKEN_RE.finditer(raw):
        kind = m.lastgroup or ""  # every alternative of the pattern is a named group
        if kind == "word":
            out.append(Token("word", m.group(), m.start() + 1, m.group(4).upper(), m.group(5)))
        else:
            out.append(Token(kind, m.group(), m.start() + 1))
    return out


def split_lines(text: str) -> list[str]:
    """Lines of ``text`` split at CR LF, CR or LF (as Python's universal newlines), no line ends."""
    lines = _NEWLINE_RE.split(text)
    if lines and lines[-1] == "":
        lines.pop()
    return lines


def block_words(raw: str, file: str, line: int) -> tuple[Words, int]:
    """The words of one block and a flag: 0 plain, 1 block delete ``/``, 2 the ``%`` mark.

    Raises :class:`NCError` (with the column) if the line is not in the language.
    """
    s = raw
    ok, blank = _BLOCK_OK, _WS_CHARS
    if "(" in s or ";" in s or ")" in s:
        if _CUT in s:  # the line holds the placeholder itself: let the tokens decide
            return _block_words_from_tokens(raw, file, line)
        s = _COMMENT_RE.sub(_CUT, s)
        if "(" in s or ")" in s:
            raise line_error(raw, file, line)
        ok, blank = _BLOCK_OK_CUT, _WS_CHARS + _CUT
    s = s.strip(blank)
    if not s:
        return _EMPTY, 0
    flag = 0
    c = s[0]
    if c == "/":
        flag = 1
        s = s[2:] if len(s) > 1 and "1" <= s[1] <= "9" else s[1:]
    elif c == "%":
        if s != "%":
            raise line_error(raw, file, line)
        return _EMPTY, 2
    if not s.isascii():
        raise line_error(raw, file, line)
    s = s.upper()
    if ok.fullmatch(s) is None:
        raise line_error(raw, file, line)
    return _WORD_RE.findall(s), flag


def _block_words_from_tokens(raw: str, file: str, line: int) -> tuple[Words, int]:
    """:func:`block_words` by the layout tokenizer (the slow path, for rare lines)."""
    err = line_error(raw, file, line)
    if err.reason != "unreadable block":
        raise err
    toks = tokenize(raw)
    code = [t for t in toks if t.kind in ("word", "delete", "percent")]
    first = code[0].kind if code else ""
    flag = 2 if first == "percent" else 1 if first == "delete" else 0
    return [(t.letter, t.number) for t in toks if t.kind == "word"], flag


def undecodable(file: str, data: bytes, exc: UnicodeDecodeError, first_line: int = 1) -> NCError:
    """NCError for bytes of ``data`` (text from line ``first_line`` on) that are not UTF-8."""
    start = exc.start
    line = first_line + data.count(b"\n", 0, start)
    column = start - data.rfind(b"\n", 0, start)  # 1-based byte column within the line
    return NCError(
        f"not a text file (UTF-8 / ASCII): {exc.reason}", file=file, line=line, column=column
    )


def word_tokens(raw: str) -> list[Token]:
    """The word tokens of a line (for mapping a word's index back to its column)."""
    return [t for t in tokenize(raw) if t.kind == "word"]


class _Where(TypedDict):
    file: str
    line: int
    column: int


def line_error(raw: str, file: str, line: int) -> NCError:
    """The NCError describing why ``raw`` is not a valid block (first problem found)."""
    seen = ""  # "" nothing yet, "code" words or "/", "%" the tape mark
    prev = None
    for t in tokenize(raw):
        where = _Where(file=file, line=line, column=t.column)
        if t.kind == "bad":
            ch = t.text[0]
            if ch == "(":
                if "(" in t.text[1:]:
                    return NCError("'(' inside a comment: comments do not nest", word="(", **where)
                return NCError("comment '(' is not closed on this line", word="(", **where)
            if ch == ")":
                return NCError("')' without an opening '('", word=")", **where)
            if ch.isascii() and ch.isalpha():
                return NCError(f"letter '{ch}' is not followed by a number", word=ch, **where)
            if ch in "0123456789" and prev is not None and prev.kind == "word":
                return NCError(
                    f"number has more than {MAX_INT_DIGITS} digits before the decimal point",
                    word=prev.text.strip() + ch,
                    **_Where(file=file, line=line, column=prev.column),
                )
            if ch in "0123456789.+-":
                return NCError("number without an address letter", word=ch, **where)
            return NCError(f"character {ch!r} is not allowed in a block", word=ch, **where)
        if t.kind == "delete" and seen:
            return NCError("block delete '/' must start the block", word=t.text, **where)
        if t.kind == "percent" and seen or t.kind in ("word", "delete") and seen == "%":
            return NCError("'%' must stand alone on its line", word=t.text, **where)
        if t.kind in ("word", "percent", "delete"):
            seen = "%" if t.kind == "percent" else "code"
        prev = t
    return NCError("unreadable block", file=file, line=line, column=1)


def word_error(raw: str, index: int, reason: str, file: str, line: int) -> NCError:
    """NCError about the ``index``-th word of a block (columns found by re-reading the line)."""
    toks = word_tokens(raw)
    if 0 <= index < len(toks):
        t = toks[index]
        return NCError(reason, file=file, line=line, column=t.column, word=t.text.strip())
    return NCError(reason, file=file, line=line, column=1)


def find_word(raw: str, letter: str) -> int:
    """Index among the block's words of the first word with ``letter`` (upper-case), or -1."""
    for i, t in enumerate(word_tokens(raw)):
        if t.letter == letter:
            return i
    return -1
