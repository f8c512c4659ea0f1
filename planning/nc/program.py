"""A program as its text, editable word by word without disturbing anything else.

:class:`Program` keeps the source lines verbatim (one block per line: block ``i`` is line
``i + 1``, blank and comment-only lines included), so ``Program.parse(text).text() == text`` for
any text with uniform line endings. Edits re-tokenise only the block they touch and change only
the words they name; comments, spacing, case, N numbers and number formats elsewhere stay.

Editing API (used by the feed post-processor)::

    prog = Program.read("part.nc")
    prog.set_word(12, "F", 250)             # replace or add the F word of block 12
    prog.get_word(12, "X")                  # -> "10.5" (number text as written) or None
    prog.remove_word(12, "F")
    prog.replace_blocks({40: [{"X": 5, "F": 200}, {"X": 10, "F": 300}]})  # 1 block -> 2
    prog.write("part-out.nc")

New words are formatted in the program's style (:class:`NumberStyle`: decimals, trailing-dot
integers like ``10.``) and separated like the block they join (spaces or none). Blocks built by
:meth:`Program.format_block` take the N word, block-delete mark and indentation of the block they
replace; the first one also keeps its comments.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from planning.nc import _lexer
from planning.nc._lexer import _NEWLINE_RE, split_lines
from planning.nc.errors import NCError

INTEGER_LETTERS = frozenset("GMNOTDHLSP")  # written without a decimal point when integral
Value = float | int | str
#: A word mapping's value: a list or tuple repeats the letter (``{"G": [17, 90]}``)
BlockValue = Value | list[Value] | tuple[Value, ...]


@dataclass(frozen=True)
class NumberStyle:
    """How numbers are written: at most ``decimals`` places, trailing zeros dropped, integers
    written ``10.`` when ``trailing_dot`` (Fanuc habit) else ``10``."""

    decimals: int = 4
    trailing_dot: bool = False

    def format(self, value: float, letter: str = "") -> str:
        if letter in INTEGER_LETTERS:
            iv = round(float(value))
            if abs(iv - float(value)) > 1e-9:
                return format_number(float(value), self.decimals, False)  # G90.1, S1.5
            return str(iv)
        return format_number(float(value), self.decimals, self.trailing_dot)


def format_number(value: float, decimals: int, trailing_dot: bool = False) -> str:
    """``value`` rounded to ``decimals`` places without trailing zeros (never ``-0``)."""
    s = f"{value:.{decimals}f}"
    if "." in s:
        s = s.rstrip("0")
    if s.startswith("-") and s.strip("-0.") == "":
        s = s[1:]
    if s.endswith("."):
        s = s if trailing_dot else s[:-1]
    return s


def infer_style(lines: Iterable[str], limit: int = 500) -> NumberStyle:
    """Decimals and trailing-dot habit of the coordinate words in the first ``limit`` lines."""
    decimals, dots, seen = 0, 0, 0
    for raw in lines:
        if seen >= limit:
            break
        seen += 1
        for t in _lexer.word_tokens(raw):
            if t.letter in "XYZIJKRF" and "." in t.number:
                frac = t.number.split(".", 1)[1]
                decimals = max(decimals, len(frac))
                dots += frac == ""
    return NumberStyle(decimals=min(max(decimals, 3), 6), trailing_dot=dots > 0)


@dataclass
class Program:
    """The lines of an NC program (without line ends) and how to write them back.

    lines : list of str — block ``i`` is ``lines[i]`` (source line ``i + 1``)
    file : str — name for messages
    newline : str — line end written back (the source's first one)
    final_newline : bool — whether the text ends with a line end
    """

    lines: list[str]
    file: str = "<program>"
    newline: str = "\n"
    final_newline: bool = True
    _style: NumberStyle | None = field(default=None, repr=False, compare=False)

    # ------------------------------------------------------------------ reading / writing
    @classmethod
    def parse(cls, text: str, file: str = "<program>", *, check: bool = True) -> Program:
        """Split ``text`` into blocks; with ``check`` every block is lexed (syntax errors raise
        NCError now rather than at interpretation)."""
        m = _NEWLINE_RE.search(text)
        newline = m.group() if m else "\n"
        final = bool(text) and text[-1] in "\r\n"
        prog = cls(split_lines(text), str(file), newline, final)
        if check:
            for i, raw in enumerate(prog.lines):
                _lexer.block_words(raw, prog.file, i + 1)
        return prog

    @classmethod
    def read(cls, path: str | Path, *, check: bool = True) -> Program:
        """Read a program file (UTF-8/ASCII); NCError if it cannot be read."""
        p = Path(path)
        try:
            data = p.read_bytes()
            text = data.decode("utf-8-sig")  # a BOM is dropped (and not written back)
        except UnicodeDecodeError as exc:
            raise _lexer.undecodable(str(p), data, exc) from None
        except OSError as exc:
            raise NCError(f"cannot read the program: {exc.strerror}", file=str(p)) from None
        return cls.parse(text, str(p), check=check)

    @classmethod
    def from_blocks(
        cls,
        blocks: Iterable[str | Mapping[str, BlockValue]],
        file: str = "<program>",
        style: NumberStyle | None = None,
    ) -> Program:
        """A new program from block texts or word mappings (``{"G": 1, "X": 10, "F": 300}``)."""
        prog = cls([], str(file), _style=style or NumberStyle())
        prog.lines = [b if isinstance(b, str) else prog.format_block(b) for b in blocks]
        return prog

    def text(self) -> str:
        """The program text (unchanged blocks exactly as read)."""
        body = self.newline.join(self.lines)
        return body + self.newline if self.final_newline and self.lines else body

    def write(self, path: str | Path) -> None:
        """Write :meth:`text` to ``path`` (line ends as in the source)."""
        Path(path).write_bytes(self.text().encode("utf-8"))

    def __len__(self) -> int:
        return len(self.lines)

    @property
    def style(self) -> NumberStyle:
        if self._style is None:
            self._style = infer_style(self.lines)
        return self._style

    # ------------------------------------------------------------------ reading words
    def _check(self, block: int) -> None:
        if not 0 <= block < len(self.lines):
            raise NCError(
                f"block index {block} out of range (program has {len(self.lines)} blocks)",
                file=self.file,
            )

    def words(self, block: int) -> list[_lexer.Token]:
        """Word tokens of a block (letter, number text, column)."""
        self._check(block)
        return _lexer.word_tokens(self.lines[block])

    def get_word(self, block: int, letter: str) -> str | None:
        """Number text of the first ``letter`` word of a block, or None."""
        letter = letter.upper()
        return next((t.number for t in self.words(block) if t.letter == letter), None)

    # ------------------------------------------------------------------ editing
    def set_word(self, block: int, letter: str, value: Value) -> None:
        """Replace the ``letter`` word of ``block`` (or add it after the last word).

        Only that word's characters change. ``value`` is a number (formatted in the program's
        style) or the number text to write. G and M words, which may repeat, are edited with
        :meth:`replace_word`.
        """
        letter = _letter(letter)
        if letter in "GM":
            raise NCError(
                f"{letter} words may repeat in a block; use replace_word",
                file=self.file,
                line=block + 1,
                word=letter,
            )
        self._check(block)
        num = value if isinstance(value, str) else self.style.format(value, letter)
        toks = _lexer.tokenize(self.lines[block])
        for k, t in enumerate(toks):
            if t.kind == "word" and t.letter == letter:
                toks[k] = _lexer.Token("word", t.text[0] + num, t.column, letter, num)
                self.lines[block] = "".join(x.text for x in toks)
                return
        if any(t.kind == "percent" for t in toks):
            raise NCError(
                "the '%' tape mark line cannot take words", file=self.file, line=block + 1
            )
        self.lines[block] = _insert_word(toks, letter + num)

    def replace_word(self, block: int, old: str, new: str | None) -> None:
        """Replace the word written ``old`` (e.g. ``"G1"``, compared by letter and value) by
        the text ``new``, or delete it (and one space before it) when ``new`` is None."""
        self._check(block)
        want = _lexer.word_tokens(old)
        if len(want) != 1:
            raise NCError(f"old must be one word, got {old!r}", file=self.file, line=block + 1)
        w = want[0]
        toks = _lexer.tokenize(self.lines[block])
        for k, t in enumerate(toks):
            if t.kind == "word" and t.letter == w.letter and float(t.number) == float(w.number):
                if new is None:
                    del toks[k]
                    if k > 0 and toks[k - 1].kind == "space" and (k - 1 > 0):
                        del toks[k - 1]
                else:
                    toks[k] = _lexer.Token("word", new, t.column)
                self.lines[block] = "".join(x.text for x in toks)
                return
        raise NCError("block has no such word", file=self.file, line=block + 1, word=old)

    def remove_word(self, block: int, letter: str) -> None:
        """Delete the first ``letter`` word of a block (no-op if absent)."""
        letter = _letter(letter)
        self._check(block)
        for t in _lexer.tokenize(self.lines[block]):
            if t.kind == "word" and t.letter == letter:
                self.replace_word(block, t.letter + t.number, None)
                return

    def format_block(self, words: Mapping[str, BlockValue], like: int | None = None) -> str:
        """Text of a new block from ``{letter: value}`` (in order; list values repeat a letter,
        e.g. ``{"G": [17, 90]}``), styled like block ``like``: its separator, indentation,
        block delete mark and N word (kept as written unless ``words`` has an N)."""
        sep, prefix = " ", ""
        if like is not None:
            self._check(like)
            toks = _lexer.tokenize(self.lines[like])
            sep = _separator(toks)
            pre = []
            for t in toks:
                if t.kind in ("space", "delete"):
                    pre.append(t.text)
                elif t.kind == "word" and t.letter == "N" and "N" not in {k.upper() for k in words}:
                    pre.append(t.text + sep)
                    break
                else:
                    break
            prefix = "".join(pre)
            if prefix and not prefix[-1].isspace() and sep:
                prefix += sep
        parts = []
        for letter, value in words.items():
            letter = _letter(letter)
            for item in value if isinstance(value, list | tuple) else (value,):
                parts.append(
                    letter + (item if isinstance(item, str) else self.style.format(item, letter))
                )
        return prefix + sep.join(parts)

    def replace_blocks(self, edits: Mapping[int, Sequence[str | Mapping[str, Value]]]) -> list[int]:
        """Replace each block ``i`` in ``edits`` by the given blocks (texts or word mappings
        formatted with :meth:`format_block` like block ``i``; a first new block given as a
        mapping also gets block ``i``'s comments, texts are used verbatim). Untouched blocks stay
        as they are.

        Returns ``new_index`` with ``new_index[i]`` = index of the first block that block ``i``
        became (the others follow it), so callers can map old blocks to new ones.
        """
        for i in edits:
            self._check(i)
        out: list[str] = []
        new_index: list[int] = []
        for i, raw in enumerate(self.lines):
            new_index.append(len(out))
            if i not in edits:
                out.append(raw)
                continue
            comments = "".join(t.text for t in _lexer.tokenize(raw) if t.kind == "comment")
            for j, b in enumerate(edits[i]):
                text = b if isinstance(b, str) else self.format_block(b, like=i)
                if j == 0 and comments and not isinstance(b, str):
                    text = f"{text} {comments}" if text.strip() else text + comments
                out.append(text)
        self.lines = out
        return new_index


def _letter(letter: str) -> str:
    letter = letter.upper()
    if len(letter) != 1 or not ("A" <= letter <= "Z"):
        raise NCError(f"an address is one letter A-Z, got {letter!r}")
    return letter


def _separator(toks: list[_lexer.Token]) -> str:
    """' ' if the block separates its words by spaces, '' if it runs them together."""
    words = [k for k, t in enumerate(toks) if t.kind == "word"]
    for a, b in zip(words, words[1:]):
        return " " if b > a + 1 and toks[a + 1].kind == "space" else ""
    return " "


def _insert_word(toks: list[_lexer.Token], word: str) -> str:
    """Text of the block with ``word`` added after its last word (before comments)."""
    sep = _separator(toks)
    last = max((k for k, t in enumerate(toks) if t.kind in ("word", "delete")), default=-1)
    texts = [t.text for t in toks]
    if last < 0:
        lead = 0
        while lead < len(toks) and toks[lead].kind == "space":
            lead += 1
        rest = "".join(texts[lead:])
        return "".join(texts[:lead]) + word + (" " + rest if rest else "")
    if toks[last].kind == "delete":
        sep = ""
    return "".join(texts[: last + 1]) + sep + word + "".join(texts[last + 1 :])
