"""A program written out for one controller dialect: Fanuc, LinuxCNC or GRBL 1.1.

:func:`for_dialect` takes a program as it reads in its ``source`` dialect (what the planners write
is Fanuc-style) and returns the same program for the ``dialect`` controller, block by block, so
that the controller moves exactly as the source interprets: the result is interpreted back
(:mod:`planning.nc.interpreter`, in the target dialect) and compared segment by segment with the
source (end points within 1e-6 mm, same feeds, dwells, spindle); a mismatch or a block the target
cannot take raises :class:`~planning.nc.NCError` instead of writing a program that would move
otherwise. A GRBL program is also run through :func:`planning.nc.dialect.check_dialect` (GRBL
1.1h's own parser rules, lines sent as written): nothing it refuses is written.

What changes, per target (blocks the target takes as written stay byte for byte):

* ``fanuc``: O number, N words and ``%`` as they are; ISO code: a decimal point in every length
  and angle word (``Z87.``: on a Fanuc without DPI ``Z87`` is 87 least increments, 0.087 mm),
  upper-case words, ``( )`` comments (``;`` is the end of block there); no ``G90.1``/``G91.1``
  (a Fanuc's arc centres are always relative: centres under G90.1 are rewritten relative). From
  GRBL/LinuxCNC: ``G4 P<s>`` becomes ``G4 X<s>``, canned cycles are expanded (their rules differ).
* ``linuxcnc``: ``%`` on the first and last line only (LinuxCNC's wrapping; nothing after the
  end), no O word (an O word at the start of a line is a LinuxCNC subroutine call), M30 appended
  when the program has no M2/M30; dwells in seconds (``G4 P<s>``, Fanuc's ``G4 X`` and ``P`` ms
  converted); canned cycles expanded (LinuxCNC positions and pecks otherwise: see
  :mod:`planning.nc.canned`); G29 expanded; ``G80`` left out of a block that names another
  motion code (one modal group in LinuxCNC); a ``G94`` that would clear the feed (LinuxCNC
  clears F on every G94) left out when the feed mode is already G94.
* ``grbl`` (GRBL 1.1): no ``%`` lines, blank lines or blocks after the end; no O word; no M6
  unless the machine has a tool changer (``tool_changer``): a change of tool becomes ``M5`` (if
  the spindle runs), ``M0`` with a comment naming the tool (the operator changes it, then cycle
  start) and the spindle restarted; the first tool's ``M6`` is left out (load it before the
  start); no G43/H (tool length offsets are the operator's: GRBL has G43.1 only), no D, no
  G98/G99, no G64 (GRBL has G61 only); canned cycles G81-G83 and G29 expanded into
  ``G0``/``G1``/``G4`` moves; ``G90.1`` becomes ``G91.1`` with the arc centres rewritten
  relative; dwells ``G4 P<s>``; block-delete (``/``) blocks left out (GRBL ignores the ``/``:
  they would run). Every line is at most :data:`GRBL_LINE_CHARS` characters comments included
  (GRBL's 80-byte line buffer holds 79 and a NUL; comments count in its 128-byte serial buffer):
  a longer comment moves to comment lines of its own, word-wrapped. G41/G42 cutter compensation
  and A/B/C words cannot be written for GRBL (an error says so).

Expanded moves are the interpreter's own (``it.execute`` of the block: for canned cycles
:func:`planning.nc.canned.drill_hole` with the modal state of the block), written in absolute
program coordinates (a ``G90`` ... ``G91`` pair around them under G91) in the program's units,
6 decimals in mm, 8 in inches; the block's N word, F, S, T, M words and modal codes go on the
line before them, M0/M1/M2/M30 on the line after.
"""

from __future__ import annotations

import textwrap
from collections.abc import Callable
from typing import TYPE_CHECKING

from planning.nc import _lexer, dialects
from planning.nc._codes import INCH_MM, gkey
from planning.nc._post_check import MOTION_TOL_MM as MOTION_TOL_MM
from planning.nc._post_check import _is_m6, _verify
from planning.nc.arcs import PLANE_AXES
from planning.nc.dialect import check_dialect, refused
from planning.nc.errors import NCError
from planning.nc.interpreter import Interpreter
from planning.nc.motion import ARC_CCW, ARC_CW, DWELL, LINE, RAPID, Motion
from planning.nc.program import Program, format_number
from planning.nc.state import ModalState

if TYPE_CHECKING:
    from analysis.config import MachineConfig

DIALECTS = dialects.DIALECTS
GRBL_LINE_CHARS = 79  # GRBL 1.1's LINE_BUFFER_SIZE 80 holds 79 characters and the NUL

_CYCLES = frozenset(range(730, 900, 10)) - {800}  # G73, G74, G76, G81..G89 (G80 cancels)
_RETURN_MODES = frozenset({980, 990})  # G98 / G99
# group-0 codes: a block with one is not a canned-cycle hole even in a cycle mode
_NON_MODAL = frozenset({40, 100, 280, 281, 290, 300, 301, 520, 530, 920, 921, 922, 923})
_GROUP1 = frozenset({0, 10, 20, 30}) | _CYCLES
_STOPS = frozenset({0, 1, 2, 30})  # M codes that act after the block's motion
_POINT_LETTERS = frozenset("XYZIJKRQUVWABC")  # lengths and angles: Fanuc wants the point


def default_dialect(machine: MachineConfig | None) -> str:
    """The machine's controller dialect, or :data:`planning.nc.dialects.DEFAULT` (Fanuc) without
    a machine."""
    return machine.dialect if machine is not None else dialects.DEFAULT


def for_dialect(
    program: Program,
    dialect: str,
    machine: MachineConfig | None = None,
    *,
    source: str | None = None,
    tool_changer: bool | None = None,
) -> Program:
    """``program`` (read in the ``source`` dialect, default the machine's, else Fanuc) written
    for a ``dialect`` controller (see the module docstring); a new Program, ``program`` is not
    changed.

    ``tool_changer`` (default: the machine config's ``tool_changer``, else False) keeps M6 for
    GRBL. Raises NCError when a block cannot be written for ``dialect`` (with its file and
    line) or, as an internal check, when the result would not move like the source.
    """
    dialect = _dialect(dialect, program.file)
    source = _dialect(source or default_dialect(machine), program.file)
    if tool_changer is None:
        tool_changer = bool(getattr(machine, "tool_changer", False))
    lines = _Rewriter(program, dialect, source, machine, tool_changer).run()
    out = _copy(program, lines)
    d = dialects.get(dialect)
    if d.post.firmware_check:  # what GRBL 1.1h would refuse line by line (planning.nc.dialect)
        bad = grbl_problems(out, tool_changer=tool_changer)
        bad += [
            str(p) for p in refused(check_dialect(out, dialect, strip=False))
            if not (tool_changer and _is_m6(p.word))
        ]  # fmt: skip
        if bad:
            raise NCError(f"cannot be written for {dialect}: {bad[0]}", file=program.file)
    _verify(program, out, dialect, source, machine, keeps_tools=d.post.full_words or tool_changer)
    return out


def grbl_problems(program: Program | str, *, tool_changer: bool = False) -> list[str]:
    """What keeps GRBL 1.1 from taking a program line by line: lines over
    :data:`GRBL_LINE_CHARS` characters (comments included), O words, M6 (unless
    ``tool_changer``), canned cycles G73-G89, G41/G42/G43. Empty when it can be streamed."""
    lines = program.lines if isinstance(program, Program) else _lexer.split_lines(program)
    out: list[str] = []
    for n, raw in enumerate(lines, 1):
        if len(raw) > GRBL_LINE_CHARS:
            out.append(f"line {n}: {len(raw)} characters (GRBL takes {GRBL_LINE_CHARS})")
        for t in _lexer.word_tokens(raw):
            v = float(t.number)
            if t.letter == "O":
                out.append(f"line {n}: O word {t.text!r} (GRBL: error:20)")
            elif t.letter == "M" and v == 6 and not tool_changer:
                out.append(f"line {n}: {t.text!r} tool change (GRBL: error:20)")
            elif t.letter == "G" and round(v * 10) in _CYCLES | {410, 420, 430}:
                out.append(f"line {n}: {t.text!r} (GRBL: error:20)")
    return out


# ---------------------------------------------------------------------------------- internals


def _dialect(name: str, file: str) -> str:
    if name not in dialects.REGISTRY:
        raise NCError(f"dialect must be one of {', '.join(DIALECTS)}, got {name!r}", file=file)
    return name


def _copy(program: Program, lines: list[str]) -> Program:
    out = Program(lines, program.file, program.newline, True)
    out._style = program.style  # noqa: SLF001 - same number style as the source
    return out


def _num(value: float, inch: bool, trailing_dot: bool = False) -> str:
    return format_number(value, 8 if inch else 6, trailing_dot)


def _seconds(value: float) -> str:
    return format_number(value, 6)


def _dwell_p(seconds: float, ms: bool) -> str:
    """A dwell's P number: milliseconds (3 decimals) or seconds (6 decimals)."""
    return format_number(seconds * 1000.0, 3) if ms else _seconds(seconds)


class _Rewriter:
    """One pass over the source blocks with an interpreter alongside (the modal state before and
    after each block, and the segments of the blocks that are expanded)."""

    def __init__(
        self, program: Program, dialect: str, source: str, machine: MachineConfig | None,
        tool_changer: bool,
    ) -> None:
        self.program = program
        self.dialect = dialect
        self.source = source
        d = self.target = dialects.get(dialect)
        self.src = dialects.get(source)
        self.post = post = d.post
        self.tool_changer = tool_changer
        # 10. (Fanuc: without the point 10 is read in least increments, 0.01 mm) or as the
        # program writes it
        self.dot = post.iso_words or program.style.trailing_dot
        self.limit = d.max_line_chars
        # canned cycles differ between dialects (LinuxCNC's positioning, GRBL has none)
        self.expand_cycles = not post.canned_cycles or dialect != source
        self._normalizes = post.iso_words or post.paren_comments
        self.it = Interpreter(
            machine, strict=True, file=program.file, dialect=source,
            cutter_comp="warn" if d.cutter_comp else "refuse",
        )  # fmt: skip

    # ------------------------------------------------------------------ the pass
    def run(self) -> list[str]:
        out: list[str] = []
        it = self.it
        for i, raw in enumerate(self.program.lines):
            toks = _lexer.tokenize(raw)
            st0 = it.state.copy()
            gs = {gkey(t.number) for t in toks if t.kind == "word" and t.letter == "G"}
            seg = None
            if self._needs_segments(gs, st0):
                seg = it.execute(raw, line=i + 1, block=i)
            else:
                it.skip([raw], first_line=i + 1)
            out += self._block(i, raw, toks, gs, st0, it.state, seg)
        if self.post.appends_m30 and not it.state.ended:
            out.append("M30")
        if self.post.wraps_percent:
            out = ["%", *out, "%"]
        if self.limit is not None:
            out = [piece for line in out for piece in self._fit(line, self.limit)]
        return out

    def _needs_segments(self, gs: set[int], st0: ModalState) -> bool:
        if 290 in gs and not self.post.g29:
            return True
        if not self.post.absolute_arc_centres and (st0.arc_absolute or 901 in gs):
            return True
        return self.expand_cycles and (st0.motion >= 81 or bool(gs & _CYCLES))

    def _fail(self, i: int, raw: str, reason: str) -> NCError:
        return NCError(
            f"cannot be written for {self.dialect}: {reason}", file=self.program.file,
            line=i + 1, word=raw.strip()[:40],
        )  # fmt: skip

    def _block(self, i: int, raw: str, toks: list[_lexer.Token], gs: set[int], st0: ModalState,
               st1: ModalState, seg: Motion | None) -> list[str]:  # fmt: skip
        rules = self.post
        if st0.ended or st0.tape_marks >= 2:  # after the end: the controller ignores it too
            return [raw] if rules.keeps_tape else []
        kinds = [t.kind for t in toks if t.kind != "space"]
        if "percent" in kinds:
            return [raw] if rules.keeps_tape else []
        words = [t for t in toks if t.kind == "word"]
        if not words or kinds[0] == "delete":  # (delete: skipped with block delete on)
            if rules.drops_blank_and_deleted and (words or not raw.strip()):
                return []  # (GRBL ignores the '/': the block would run)
            return [self._normal(_Block(toks)).text()] if self._normalizes else [raw]
        b = _Block(toks)
        pre: list[str] = []
        post: list[str] = []
        if not rules.absolute_arc_centres:
            self._arc_centres(b, gs, st1, seg)
        if not rules.keeps_tape:
            b.drop(lambda t: t.letter == "O")
        if not rules.g80_with_motion and 800 in gs and gs & _GROUP1:
            b.drop(lambda t: t.letter == "G" and gkey(t.number) == 800)
        if self.expand_cycles:
            b.drop(lambda t: t.letter == "G" and gkey(t.number) in _RETURN_MODES)
        if 40 in gs:
            self._dwell(b)
        if self.target.g94_clears_feed and 940 in gs:
            if st0.feed_mode == 94 and st0.feed_mm_min == st0.feed_mm_min and not b.has("F"):
                b.drop(lambda t: t.letter == "G" and gkey(t.number) == 940)
        if not rules.full_words:
            self._limited_words(i, raw, b, gs, st0, st1, seg, pre, post)
        if self._normalizes:
            self._normal(b)
        cycle = self.expand_cycles and st1.motion >= 81 and not gs & _NON_MODAL
        if cycle or (290 in gs and not rules.g29):
            if cycle:
                b.drop(lambda t: t.letter in "XYZRQPL" or (t.letter == "G" and gkey(t.number)
                                                             in _CYCLES))  # fmt: skip
            else:
                b.drop(lambda t: t.letter in "XYZ" or (t.letter == "G" and gkey(t.number) == 290))
            return pre + self._expand(i, raw, b, st0, st1, seg) + post
        text = b.text()
        if not text.strip():
            return pre + post
        return [*pre, text, *post]

    # ------------------------------------------------------------------ word rewrites
    def _normal(self, b: _Block) -> _Block:
        return b.iso(points=self.post.iso_words, parens=self.post.paren_comments)

    def _dwell(self, b: _Block) -> None:
        """G4: P in ms (Fanuc) or s (GRBL, LinuxCNC), X in s; written as the target reads."""
        src_ms, dst_ms = self.src.dwell_p_ms, self.target.dwell_p_ms
        for k, t in b.words():
            if t.letter not in "PX":
                continue
            s = float(t.number)
            if t.letter == "P" and src_ms:
                s /= 1000.0
            if self.post.dwell_word == "X":
                if t.letter == "P" and not src_ms:
                    b.set(k, "X" + _seconds(s))
            elif t.letter == "X" or src_ms != dst_ms:
                b.set(k, "P" + _dwell_p(s, dst_ms))

    def _limited_words(self, i: int, raw: str, b: _Block, gs: set[int], st0: ModalState,
                       st1: ModalState, seg: Motion | None, pre: list[str],
                       post: list[str]) -> None:  # fmt: skip
        """GRBL 1.1's words: no G43/H/D/G64, M6 -> an M0 pause (unless a tool changer), no
        A/B/C."""
        b.drop(lambda t: t.letter == "G" and gkey(t.number) == 430)
        b.drop(lambda t: t.letter in "HD")  # G43 H is gone; D only with G41/G42 (refused)
        if 640 in gs:  # G64 P/Q: blending tolerances; GRBL has G61 only
            b.drop(lambda t: t.letter == "G" and gkey(t.number) == 640)
            if 40 not in gs and st1.motion < 81:
                b.drop(lambda t: t.letter in "PQ")
        m6 = [k for k, t in b.words() if t.letter == "M" and float(t.number) == 6]
        if m6 and not self.tool_changer:
            b.drop(lambda t: t.letter == "M" and float(t.number) == 6)
            if st0.tool != 0 and st1.tool != st0.tool:
                if st0.spindle_dir:
                    pre.append("M5")
                pre.append(f"M0 (change to tool T{st1.tool}, then cycle start)")
                spindle_m = any(t.letter == "M" and float(t.number) in (3, 4, 5)
                                for _, t in b.words())  # fmt: skip
                if st0.spindle_dir and not spindle_m:
                    post.append("M3" if st1.spindle_dir > 0 else "M4")
        for _, t in b.words():
            if t.letter in "ABC":
                raise self._fail(i, raw, f"GRBL 1.1 has 3 axes: no {t.letter} word")

    def _arc_centres(self, b: _Block, gs: set[int], st1: ModalState, seg: Motion | None) -> None:
        """GRBL and Fanuc have no G90.1 (absolute arc centres): GRBL gets G91.1 instead, Fanuc
        neither (its centres are always relative); the centres of arcs under G90.1 are written
        relative to the arc's start."""
        if gs & {901, 911}:
            for k, t in reversed(b.words()):
                key = gkey(t.number) if t.letter == "G" else 0
                if key == 901 and self.post.g91_1:
                    b.set(k, "G91.1")
                elif key in (901, 911) and not self.post.g91_1:
                    b.drop_at(k)
        if not st1.arc_absolute or seg is None or not len(seg):
            return
        if int(seg.kind[0]) not in (ARC_CW, ARC_CCW):
            return
        scale = INCH_MM if st1.inch else 1.0
        ia, ib, _ = PLANE_AXES[int(seg.plane[0])]
        for ax in (ia, ib):
            letter = "IJK"[ax]
            value = (float(seg.center[0, ax]) - float(seg.start[0, ax])) / scale
            b.put(letter, letter + _num(value, st1.inch, self.dot))

    # ------------------------------------------------------------------ expansion
    def _expand(self, i: int, raw: str, b: _Block, st0: ModalState, st1: ModalState,
                seg: Motion | None) -> list[str]:  # fmt: skip
        """The block's own moves (canned-cycle holes, G29) as G0 / G1 / G4 lines after a line
        with what else the block says; stops and ends after them."""
        n_word = b.take(lambda t: t.letter == "N")
        stops = b.take(lambda t: t.letter == "M" and float(t.number) in _STOPS)
        head = " ".join(t.text for t in n_word)
        rest = b.text()
        lines = [f"{head} {rest}".strip()] if rest or not seg else []
        moves = self._moves(i, raw, seg, st0, st1)
        if moves and not st1.absolute:
            moves[0] = "G90 " + moves[0]
            moves.append("G91")
        if moves and not lines:
            moves[0] = f"{head} {moves[0]}".strip()
        lines = [x for x in lines if x] + moves
        if stops:
            lines.append(" ".join(t.text for t in stops))
        return lines

    def _moves(self, i: int, raw: str, seg: Motion | None, st0: ModalState,
               st1: ModalState) -> list[str]:  # fmt: skip
        if seg is None or not len(seg):
            return []
        inch = st1.inch
        scale = INCH_MM if inch else 1.0
        org = st1.origin_mm
        cur = [_num((st0.position_mm[a] - org[a]) / scale, inch, self.dot) for a in range(3)]
        out: list[str] = []
        for k in range(len(seg)):
            kind = int(seg.kind[k])
            if kind == DWELL:
                t = float(seg.dwell_s[k])
                if self.post.dwell_word == "X":
                    out.append(f"G4 X{format_number(t, 6, True)}")
                else:
                    out.append(f"G4 P{_dwell_p(t, self.target.dwell_p_ms)}")
                continue
            if kind not in (RAPID, LINE):
                raise self._fail(i, raw, "an arc in an expanded block (internal)")
            words = ["G0" if kind == RAPID else "G1"]
            for a in range(3):
                txt = _num((float(seg.end[k, a]) - org[a]) / scale, inch, self.dot)
                if txt != cur[a]:
                    words.append("XYZ"[a] + txt)
                    cur[a] = txt
            if len(words) == 1:  # a move of no length still moves (the interpreter keeps it)
                words.append("Z" + cur[2])
            out.append(" ".join(words))
        return out

    # ------------------------------------------------------------------ line length
    def _fit(self, line: str, limit: int) -> list[str]:
        """A line of at most ``limit`` characters: its comments moved to comment lines of their
        own (word-wrapped) when it is longer; the words without spaces if they still do not
        fit."""
        if len(line) <= limit:
            return [line]
        toks = _lexer.tokenize(line)
        comments = [t.text for t in toks if t.kind == "comment"]
        code = " ".join("".join(t.text for t in toks if t.kind != "comment").split())
        if len(code) > limit:
            code = "".join(code.split())  # spaces are not needed between words
        if len(code) > limit:
            raise NCError(
                f"cannot be written for {self.dialect}: the block is {len(code)} characters "
                f"without spaces and comments (the controller takes {limit})",
                file=self.program.file, word=line[:40],
            )  # fmt: skip
        out = [piece for c in comments for piece in _wrap_comment(c, limit)]
        return [*out, code] if code else out


def _comment_text(text: str) -> str:
    """The text of a ``( )`` or ``;`` comment, safe inside ( ): no parentheses, one line."""
    body = text[1:-1] if text.startswith("(") else text[1:]
    return " ".join(body.replace("(", "[").replace(")", "]").split())


def _wrap_comment(text: str, limit: int) -> list[str]:
    return [f"({piece})" for piece in textwrap.wrap(_comment_text(text), limit - 2)]


class _Block:
    """A block's tokens, edited word by word (spacing kept: a dropped word takes one space)."""

    def __init__(self, toks: list[_lexer.Token]) -> None:
        self.toks = list(toks)

    def words(self) -> list[tuple[int, _lexer.Token]]:
        return [(k, t) for k, t in enumerate(self.toks) if t.kind == "word"]

    def has(self, letter: str) -> bool:
        return any(t.letter == letter for _, t in self.words())

    def iso(self, *, points: bool = True, parens: bool = True) -> _Block:
        """Fanuc's ISO code: upper-case words, a decimal point in every length or angle word
        (``X10`` is 10 least increments on a Fanuc without DPI; ``X10.`` is 10 mm everywhere)
        (``points``), ``( )`` comments (``;`` is the end of block there) (``parens``)."""
        for k, t in enumerate(self.toks):
            if t.kind == "word" and points:
                num = t.number
                if t.letter in _POINT_LETTERS and "." not in num:
                    num += "."
                text = t.letter + num
                if text != t.text:
                    self.toks[k] = _lexer.Token("word", text, t.column, t.letter, num)
            elif t.kind == "comment" and t.text.startswith(";") and parens:
                body = _comment_text(t.text)
                self.toks[k] = _lexer.Token("comment", f"({body})" if body else "", t.column)
        return self

    def drop_at(self, k: int) -> None:
        t = self.toks[k]
        self.drop(lambda x: x is t)

    def set(self, k: int, text: str) -> None:
        t = self.toks[k]
        self.toks[k] = _lexer.Token("word", text, t.column, text[0], text[1:])

    def put(self, letter: str, text: str) -> None:
        """Replace the ``letter`` word, or add it after the last word."""
        for k, t in self.words():
            if t.letter == letter:
                self.set(k, text)
                return
        last = max(k for k, _ in self.words())
        self.toks[last + 1 : last + 1] = [
            _lexer.Token("space", " ", 0),
            _lexer.Token("word", text, 0, text[0], text[1:]),
        ]

    def take(self, pred: Callable[[_lexer.Token], bool]) -> list[_lexer.Token]:
        taken = [t for _, t in self.words() if pred(t)]
        self.drop(pred)
        return taken

    def drop(self, pred: Callable[[_lexer.Token], bool]) -> None:
        toks = self.toks
        k = 0
        while k < len(toks):
            t = toks[k]
            if t.kind == "word" and pred(t):
                del toks[k]
                if k > 0 and toks[k - 1].kind == "space":
                    del toks[k - 1]
                    k -= 1
                elif k < len(toks) and toks[k].kind == "space":
                    del toks[k]
                continue
            k += 1

    def text(self) -> str:
        return "".join(t.text for t in self.toks).strip()
