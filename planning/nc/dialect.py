"""What a controller answers to each line of a program: GRBL 1.1h (modelled on its source), and
the controls that read ISO code (Fanuc, LinuxCNC ...: coarser rules, each dialect's
:class:`~planning.nc.dialects.LineRules`).

:func:`check_dialect` lists the problems of a program for one controller, each as a
:class:`DialectProblem` naming file:line:column, the word and what the controller answers
(``GRBL error:20 unsupported command``). ``severity`` is ``"error"`` when the controller refuses the
line or runs something other than the program says, ``"warning"`` when it runs it with a
difference worth knowing.

GRBL's answers come from :mod:`planning.nc.grbl`, a model of GRBL 1.1h's source.

The GRBL streamer of ``rig.dnc`` sends :func:`grbl_send_text` of each line (comments, spaces, the N
word and a lone O program number removed: what GRBL discards or does not need) and refuses a
program with any ``error`` problem before the first byte is sent.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

from planning.nc import _lexer, dialects
from planning.nc._grbl_steps import GrblResult
from planning.nc.grbl import (
    GRBL_ERRORS,
    GRBL_LINE_CHARS,
    GRBL_RX_BUFFER_SIZE,
    GrblParser,
    grbl_filter,
    grbl_send_text,
    grbl_words,
)

DIALECTS = dialects.DIALECTS
DIALECT_NAMES = dialects.titles()


# -- the checker ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class DialectProblem:
    """One line a controller would refuse (``severity`` "error") or run differently ("warning").

    line, column : 1-based, in the source; word : the word or text concerned; answer : what the
    controller answers (``error:20``, ``alarm PS0010``, ``refused``, ``runs it``); reason : why.
    """

    file: str
    line: int
    column: int
    word: str
    dialect: str
    answer: str
    reason: str
    severity: str = "error"

    def __str__(self) -> str:
        name = DIALECT_NAMES.get(self.dialect, self.dialect)
        w = f" {self.word}:" if self.word else ""
        tag = "" if self.severity == "error" else " (warning)"
        return f"{self.file}:{self.line}:{self.column}:{w} {name} {self.answer}: {self.reason}{tag}"

    def as_dict(self) -> dict[str, object]:
        return dict(self.__dict__)


def _source(program_or_text: object, file: str | None) -> tuple[list[str], str]:
    lines = getattr(program_or_text, "lines", None)
    name = file or getattr(program_or_text, "file", None) or "<program>"
    if lines is not None:
        return list(lines), str(name)
    if isinstance(program_or_text, str):
        return _lexer.split_lines(program_or_text), str(name)
    return [str(x) for x in program_or_text], str(name)  # type: ignore[attr-defined]


def check_dialect(
    program_or_text: object,
    dialect: str,
    *,
    file: str | None = None,
    strip: bool = True,
    lines: Iterable[int] | None = None,
) -> list[DialectProblem]:
    """The problems of a program for ``dialect`` (a name of :data:`planning.nc.dialects.REGISTRY`),
    in line order.

    ``program_or_text``: NC text, a :class:`~planning.nc.Program` or a sequence of lines.
    ``strip`` (GRBL): the lines are sent as :func:`grbl_send_text` leaves them, as the streamer
    does by default (``False``: sent as written). ``lines``: check only these 1-based lines (the
    GRBL parser state still follows every line before them).
    """
    d = dialects.get(dialect)
    src, name = _source(program_or_text, file)
    only = set(lines) if lines is not None else None
    if d.firmware_model:
        return _check_grbl(src, name, strip, only)
    return _check_iso(src, name, d, only)


def _grbl_problem(
    name: str, lineno: int, raw: str, sent: str, res: GrblResult, strip: bool
) -> DialectProblem:
    col, word = 1, res.word
    if strip or sent == raw:
        f = grbl_filter(raw, limit=10**9)
        # map the word back to the source: find it in the filtered text of the source line
        pos = f.text.find(word) if word else -1
        if pos >= 0:
            col = f.columns[pos]
    why = {
        20: "unsupported command",
    }.get(res.code, GRBL_ERRORS.get(res.code, "error"))
    detail = _GRBL_DETAIL.get((res.code, word[:1]), "")
    if res.code == 20 and word[:1] in "GM":
        detail = _GRBL_G_DETAIL.get(word.upper(), detail or f"{word} is not a GRBL 1.1h code")
    reason = f"{why}" + (f" ({detail})" if detail else "")
    return DialectProblem(name, lineno, col, word, "grbl", f"error:{res.code}", reason)


_GRBL_DETAIL = {
    (20, "O"): "O program numbers and o-words are not G-code words GRBL knows",
    (20, "A"): "GRBL 1.1h has X Y Z only",
    (20, "B"): "GRBL 1.1h has X Y Z only",
    (20, "C"): "GRBL 1.1h has X Y Z only",
    (20, "D"): "no cutter compensation registers",
    (20, "H"): "no tool length registers (G43.1 Z.. sets a dynamic offset)",
    (20, "Q"): "no canned cycles (Q peck depth)",
    (22, ""): "a feed move before any F word",
}
_GRBL_G_DETAIL = {
    "M6": "tool change: GRBL 1.1h has none; change the tool by hand, post the program without M6",
    "M7": "mist coolant is not compiled in (ENABLE_M7)",
    "G41": "no cutter radius compensation",
    "G42": "no cutter radius compensation",
    "G43": "only G43.1 dynamic tool length offset",
    "G81": "no canned cycles",
    "G82": "no canned cycles",
    "G83": "no canned cycles",
    "G98": "no canned-cycle return modes",
    "G99": "no canned-cycle return modes",
    "G90.1": "arc centres are always incremental (G91.1)",
    "G64": "only G61 path control",
    "G52": "no local coordinate system",
}


def _check_grbl(
    src: Sequence[str], name: str, strip: bool, only: set[int] | None
) -> list[DialectProblem]:
    out: list[DialectProblem] = []
    parser = GrblParser()
    for lineno, raw in enumerate(src, 1):
        s = raw.strip()
        if not s or s == "%":  # the streamer sends neither (and GRBL answers '%' error:1)
            continue
        want = only is None or lineno in only
        f = grbl_filter(raw)
        if want and f.block_delete:
            col = raw.index("/") + 1
            out.append(DialectProblem(
                name, lineno, col, "/", "grbl", "runs it",
                "block delete is not supported (protocol.c ignores '/'): the block would run; "
                "remove the block or the '/'",
            ))  # fmt: skip
        if want and f.realtime and not strip:
            col, ch = f.realtime[0]
            what = {"!": "feed hold", "~": "cycle start", "?": "status report"}[ch]
            out.append(DialectProblem(
                name, lineno, col, ch, "grbl", "real-time command",
                f"'{ch}' is taken as the real-time {what} wherever it stands, comments included",
            ))  # fmt: skip
        sent = grbl_send_text(raw) if strip else raw
        if strip and not sent:
            continue
        if s.startswith("$"):
            continue  # system commands: answered by GRBL's $ handler, not the g-code parser
        if not strip and len(raw.encode()) + 1 > GRBL_RX_BUFFER_SIZE - 1 and want:
            out.append(DialectProblem(
                name, lineno, 1, "", "grbl", "cannot be streamed",
                f"{len(raw) + 1} bytes with its LF: more than the {GRBL_RX_BUFFER_SIZE - 1} bytes "
                "character counting may have in GRBL's receive buffer (strip comments and spaces)",
            ))  # fmt: skip
        g = grbl_filter(sent)
        if g.overflow:
            if want:
                out.append(DialectProblem(
                    name, lineno, 1, "", "grbl", "error:11",
                    f"line overflow: {len(grbl_filter(sent, 10**9).text)} characters without "
                    f"spaces and comments; GRBL's line buffer holds {GRBL_LINE_CHARS}",
                ))  # fmt: skip
            continue
        if not g.text:
            continue
        res = parser.parse(g.text)
        if not res.ok and want:
            out.append(_grbl_problem(name, lineno, raw, sent, res, strip))
        elif res.ok and want and "M1" in _m_words(g.text):
            out.append(DialectProblem(
                name, lineno, 1, "M1", "grbl", "ignores it",
                "optional stop is not supported (gcode.c: 'Optional stop not supported. Ignore.')",
                "warning",
            ))  # fmt: skip
    return out


def _m_words(text: str) -> set[str]:
    ws = grbl_words(text) or []
    return {f"M{int(float(num))}" for ltr, num, _ in ws if ltr == "M" and num not in ("", ".")}


# -- controls that read ISO code (coarse: each dialect's LineRules) ------------------------------
_AXIS_DECIMAL = frozenset("XYZIJKRQUVW")


def _is_g4(gs: list[_lexer.Token]) -> bool:
    return any(g.number.lstrip("0+") in ("4", "4.", "4.0") for g in gs)


def _check_iso(
    src: Sequence[str], name: str, d: dialects.Dialect, only: set[int] | None
) -> list[DialectProblem]:
    out: list[DialectProblem] = []
    no_point: list[tuple[int, _lexer.Token]] = []
    rules = d.lines
    for lineno, raw in enumerate(src, 1):
        if only is not None and lineno not in only:
            continue

        def add(col: int, word: str, a: dialects.Answer, ln: int = lineno) -> None:
            out.append(DialectProblem(name, ln, col, word, d.name, a.answer, a.reason, a.severity))

        toks = _lexer.tokenize(raw)
        if rules.max_line_chars is not None and len(raw) > rules.max_line_chars:
            add(1, "", dialects.Answer("error", f"line is {len(raw)} characters; {d.title} reads "
                                       f"at most {rules.max_line_chars}"))  # fmt: skip
        words = [t for t in toks if t.kind == "word"]
        gs = [t for t in words if t.letter == "G"]
        for t in toks:
            if t.kind == "comment" and t.text.startswith(";") and rules.semicolon:
                add(t.column, ";", rules.semicolon)
            if t.kind == "word" and rules.lower_case and t.text.strip()[:1].islower():
                add(t.column, t.text.strip(), rules.lower_case)
        for t in words:
            _check_word(t, gs, rules, d, add)
            if t.letter in _AXIS_DECIMAL and rules.least_increments and "." not in t.number:
                if t.number.strip("+-0") and not (t.letter == "X" and _is_g4(gs) and rules.dwell_x):
                    no_point.append((lineno, t))
    if no_point:
        lineno, t = no_point[0]
        more = f" ({len(no_point)} such words)" if len(no_point) > 1 else ""
        out.append(DialectProblem(
            name, lineno, t.column, t.text.strip(), d.name, "reads it in least increments",
            f"{t.text.strip()} without a decimal point is {t.number} x 0.001 mm unless "
            f"parameter 3401#0 (DPI) is set{more}",
            "warning",
        ))  # fmt: skip
    out.sort(key=lambda p: (p.line, p.column))
    return out


def _check_word(
    t: _lexer.Token, gs: list[_lexer.Token], rules: dialects.LineRules, d: dialects.Dialect,
    add: Callable[[int, str, dialects.Answer], None],
) -> None:  # fmt: skip
    """One word's answers (G and M codes of other controls, O and N numbers, G4 words)."""
    w = f"{t.letter}{_num_name(t.number)}"
    text = t.text.strip()
    if t.letter == "G":
        if w in rules.refused_g:
            add(t.column, w, rules.refused_g[w])
    elif t.letter == "M":
        m = _int_or_none(t.number)
        if m is not None and m in rules.refused_m:
            add(t.column, w, rules.refused_m[m])
    elif t.letter == "O":
        v = _int_or_none(t.number)
        if rules.o_word is not None:
            add(t.column, text, rules.o_word)
        elif rules.program_number_max is not None and (v is None or v > rules.program_number_max):
            n = rules.program_number_max
            add(t.column, text, dialects.Answer(
                "alarm", f"program number needs 1 to {len(str(n))} digits (O1..O{n})"))  # fmt: skip
    elif t.letter == "N" and rules.sequence_number_max is not None:
        v = _int_or_none(t.number)
        n = rules.sequence_number_max
        if v is None or v > n:
            why = f"sequence number needs 1 to {len(str(n))} digits (N1..N{n})"
            add(t.column, text, dialects.Answer("alarm", why))
    elif t.letter == "X" and rules.dwell_x is not None and _is_g4(gs):
        add(t.column, text, rules.dwell_x)
    if t.letter == "P" and rules.dwell_p_warn_s is not None and _is_g4(gs):
        secs = float(t.number)
        if secs >= rules.dwell_p_warn_s:
            add(t.column, text, dialects.Answer(
                "dwells", f"{secs:g} s (P is seconds on {d.title}: milliseconds from a Fanuc "
                "program?)", "warning"))  # fmt: skip


def _num_name(num: str) -> str:
    try:
        v = float(num)
    except ValueError:
        return num
    return f"{v:g}" if v != int(v) else str(int(v))


def _int_or_none(num: str) -> int | None:
    try:
        v = float(num)
    except ValueError:
        return None
    return int(v) if v == int(v) and v >= 0 else None


def refused(problems: Iterable[DialectProblem]) -> list[DialectProblem]:
    """The problems that stop the program (severity ``error``)."""
    return [p for p in problems if p.severity == "error"]
