"""Word and code rules of the interpreter (private): sorting a block's words, checking and recording
the non-motion words (F S T D H O N ...).

:class:`WordRules` is a part of :class:`~planning.nc.interpreter.Interpreter`: it works on the
interpreter's :class:`~planning.nc._context.Context` (state, options, warnings).
"""

from __future__ import annotations

from planning.nc import _lexer, dialects
from planning.nc._codes import LETTERS, LETTERS_GM, M_GROUP, gkey, gname
from planning.nc._context import Codes, Context
from planning.nc._lexer import Words

# words a code takes besides the axis words (G4 P, G10 L P R ..., G30 P2, G64 P Q; M61 Q, M62 P)
_G_LETTERS = {40: "P", 100: "LPRQIJ", 300: "P", 640: "PQ"}
_M_LETTERS = {50: "P", 51: "P", 52: "P", 53: "P", 61: "Q", 62: "P", 63: "P", 64: "P", 65: "P"}


class WordRules:
    """Word checks of the Interpreter (a part: works on ``ctx``)."""

    def __init__(self, ctx: Context) -> None:
        self.ctx = ctx

    def refused(
        self, raw: str, words: Words, gcodes: Codes | None, mcodes: Codes | None, line: int
    ) -> None:
        """What the control refuses outright (GRBL 1.1's error:20): say so before anything is
        sent."""
        ctx = self.ctx
        d = ctx.rules
        for key, k in gcodes or ():
            if key in d.refused_g:
                ctx.problem(raw, k, f"{gname(key)} is not a {d.refusal_name} command", line)
        for key, k in mcodes or ():
            if key // 10 in d.refused_m:
                ctx.problem(raw, k, f"M{key // 10} is not a {d.refusal_name} command", line)
        # a line holding only an O program number (and N) is not sent: the GRBL sender strips
        # it (planning.nc.grbl.grbl_send_text), as ``nc check --dialect grbl`` reads it
        lone_o = d.strips_lone_o and [ltr for ltr, _ in words if ltr != "N"] == ["O"]
        for k, (letter, _) in enumerate(words):
            if letter in d.refused_letters and not lone_o:
                ctx.problem(raw, k, f"{d.refusal_name} has no {letter} word", line)

    def sort(
        self, raw: str, words: Words, line: int
    ) -> tuple[Codes | None, Codes | None, dict[str, str]]:
        """The block's G codes, M codes (each with its word index) and other words: the common
        block (no letter twice, at most one G and one M, all known) here, the others by
        :meth:`_sort_words`, which reports what is wrong."""
        v = dict(words)
        if len(v) != len(words) or not v.keys() <= LETTERS_GM:
            return self._sort_words(raw, words, line)
        gcodes: Codes | None = None
        mcodes: Codes | None = None
        g = v.pop("G", None)
        if g is not None:
            key = gkey(g)
            if key not in self.ctx.g_group:
                return self._sort_words(raw, words, line)  # it reports the code
            gcodes = [(key, words.index(("G", g)))]
        m = v.pop("M", None)
        if m is not None:
            key = round(float(m) * 10.0)
            if key % 10 or key // 10 not in self.ctx.known_m:
                return self._sort_words(raw, words, line)
            mcodes = [(key, words.index(("M", m)))]
        return gcodes, mcodes, v

    def _sort_words(
        self, raw: str, words: Words, line: int
    ) -> tuple[Codes | None, Codes | None, dict[str, str]]:
        """G codes, M codes (with their word index) and the other words; reports unknown codes,
        unknown letters and repeated addresses."""
        gcodes: Codes | None = None
        mcodes: Codes | None = None
        v: dict[str, str] = {}
        for k, (letter, num) in enumerate(words):
            if letter == "G":
                key = gkey(num)
                if key not in self.ctx.g_group:
                    have = dialects.knowing_g(key)  # another control's code: say whose
                    where = (
                        f" in the {self.ctx.dialect} dialect ({', '.join(have)} have it: a "
                        "machine config of that dialect)"
                        if have
                        else ""
                    )
                    self.ctx.problem(raw, k, f"unknown G-code {gname(key)}{where}", line)
                elif gcodes is None:
                    gcodes = [(key, k)]
                else:
                    gcodes.append((key, k))
            elif letter == "M":
                key = round(float(num) * 10.0)
                if key % 10 or key // 10 not in self.ctx.known_m:
                    self.ctx.problem(raw, k, f"unknown M-code M{key / 10:g}", line)
                elif mcodes is None:
                    mcodes = [(key, k)]
                else:
                    mcodes.append((key, k))
            elif letter not in LETTERS:
                self.ctx.problem(raw, k, f"unknown address letter {letter}", line)
            elif letter in v:
                raise _lexer.word_error(
                    raw, k, f"address {letter} appears twice in the block", self.ctx.file, line
                )
            else:
                v[letter] = num
        return gcodes, mcodes, v

    def words(
        self, raw: str, v: dict[str, str], fscale: float, line: int, gcodes: Codes | None,
        mcodes: Codes | None,
    ) -> None:  # fmt: skip
        """F S T D H O N P Q L R I J K and A B C: checks and recording (``fscale``: mm per unit
        of F; ``gcodes``, ``mcodes``: the block's codes, for the words G4, G10, G30, G64 and M
        codes take)."""
        st = self.ctx.state
        if "F" in v:
            self.feed(raw, v, fscale, line)
        if "S" in v:
            s = float(v["S"])
            if s < 0.0:
                raise self.ctx.fail(raw, "S", "spindle speed S must be >= 0 rpm", line)
            if s > self.ctx.spindle_max_rpm:
                self.ctx.note(
                    raw,
                    "S",
                    f"S {s:g} rpm exceeds the machine's spindle_max_rpm "
                    f"{self.ctx.spindle_max_rpm:g}",
                    line,
                )
            st.spindle_speed_rpm = s
        for letter in ("T", "D", "H", "O", "N"):
            if letter in v:
                n = self.whole(raw, v, letter, line)
                if letter == "T":
                    st.tool_selected = n
                elif letter == "D":
                    st.cutter_comp_d = n
                elif letter == "H":
                    st.tool_length_h = n
                elif letter == "O":
                    st.program_number = n
                else:
                    st.sequence_number = n
        if "A" in v or "B" in v or "C" in v:
            # Degrees whatever G20/G21; G91 makes them increments like the linear axes.
            rot = list(st.rotary_deg)
            for i, letter in enumerate("ABC"):
                if letter in v:
                    x = float(v[letter])
                    rot[i] = x if st.absolute else rot[i] + x
            self.ctx.rotary_to = (rot[0], rot[1], rot[2])
            st.rotary_named = "".join(c for c in "ABC" if c in v or c in st.rotary_named)
        mode = st.motion
        used = ""
        if mode in (2, 3):
            used = "IJKRP" if self.ctx.rules.arc_turns_p else "IJKR"  # LinuxCNC: P turns
        elif mode >= 81:
            used = "RLPQ"
        extra = None
        for letter in "IJKRPQL":
            if letter in v and letter not in used:
                if extra is None:  # the letters the block's G and M codes take
                    extra = "".join(_G_LETTERS.get(key, "") for key, _ in gcodes or ())
                    extra += "".join(_M_LETTERS.get(key // 10, "") for key, _ in mcodes or ())
                if letter not in extra:
                    self.ctx.problem(
                        raw,
                        _lexer.find_word(raw, letter),
                        f"word {letter} is not used by any code in force (motion G{mode})",
                        line,
                    )

    def whole(self, raw: str, v: dict[str, str], letter: str, line: int) -> int:
        """The value of a T D H O N word: a whole number 0..999999999."""
        n = float(v[letter])
        if n < 0 or n != int(n) or n > 999_999_999:
            raise self.ctx.fail(
                raw,
                letter,
                f"{letter} must be a whole number in 0..999999999, got {v[letter]}",
                line,
            )
        return int(n)

    def feed(self, raw: str, v: dict[str, str], scale: float, line: int) -> None:
        if self.ctx.state.feed_mode == 93:
            f = float(v["F"])
            if not f > 0.0:
                raise self.ctx.fail(
                    raw,
                    "F",
                    "inverse-time feed F must be > 0 (1/min: the move takes 1/F min)",
                    line,
                )
            self.ctx.inverse_f = f
            return
        word = float(v["F"])
        f = word * scale
        if not f > 0.0:
            raise self.ctx.fail(raw, "F", "feed F must be > 0 (mm/min, or in/min under G20)", line)
        if f > self.ctx.feed_max_mm_min:
            self.ctx.note(
                raw,
                "F",
                f"feed {f:g} mm/min exceeds the machine's feed_max_mm_min "
                f"{self.ctx.feed_max_mm_min:g}",
                line,
            )
        self.ctx.state.feed_mm_min = f
        self.ctx.state.feed_word = word

    def check_m_groups(self, raw: str, mcodes: list[tuple[int, int]], line: int) -> None:
        seen: dict[str, int] = {}
        for key, k in mcodes:
            grp = M_GROUP[key // 10]
            if grp in seen:
                raise _lexer.word_error(
                    raw,
                    k,
                    f"M{key // 10} and M{seen[grp]} are both {grp} codes and cannot share a block",
                    self.ctx.file,
                    line,
                )
            seen[grp] = key // 10
