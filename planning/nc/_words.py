"""Word and code rules of the interpreter (private): sorting a block's words, checking and recording
the non-motion words (F S T D H O N ...), and how problems become errors or warnings.

:class:`WordRules` is a mixin of :class:`~planning.nc.interpreter.Interpreter`; it uses the
interpreter's ``state``, ``file``, ``strict``, ``warnings`` and machine limits.
"""

from __future__ import annotations

from planning.nc import _lexer, dialects
from planning.nc._codes import LETTERS, M_GROUP, gkey, gname
from planning.nc.errors import NCError, NCWarning
from planning.nc.state import ModalState

# words a code takes besides the axis words (G4 P, G10 L P R ..., G30 P2, G64 P Q; M61 Q, M62 P)
_G_LETTERS = {40: "P", 100: "LPRQIJ", 300: "P", 640: "PQ"}
_M_LETTERS = {50: "P", 51: "P", 52: "P", 53: "P", 61: "Q", 62: "P", 63: "P", 64: "P", 65: "P"}


class WordRules:
    """Word checks of the Interpreter (mixin)."""

    state: ModalState
    file: str
    strict: bool
    warnings: list[NCWarning]
    _feed_max_mm_min: float
    _spindle_max_rpm: float
    _inverse_f: float
    _g_group: dict[int, int]
    _known_m: frozenset[int]
    dialect: str
    rules: dialects.Dialect

    def _problem(self, raw: str, index: int, reason: str, line: int) -> None:
        """Strict: raise; lenient: record a warning about word ``index`` of the block."""
        err = _lexer.word_error(raw, index, reason, self.file, line)
        if self.strict:
            raise err
        self._warn(err)

    def _note(self, raw: str, letter_or_index: str | int, reason: str, line: int) -> None:
        """A warning in both modes (the block is still executed as written)."""
        self._warn(self._fail(raw, letter_or_index, reason, line))

    def _warn(self, err: NCError) -> None:
        self.warnings.append(NCWarning(err.reason, err.file, err.line, err.column, err.word))

    def _fail(self, raw: str, letter_or_index: str | int, reason: str, line: int) -> NCError:
        idx = letter_or_index
        if isinstance(idx, str):
            idx = _lexer.find_word(raw, idx)
        return _lexer.word_error(raw, idx, reason, self.file, line)

    def _sort_words(self, raw: str, words, line: int):
        """G codes, M codes (with their word index) and the other words; reports unknown codes,
        unknown letters and repeated addresses."""
        gcodes: list[tuple[int, int]] | None = None
        mcodes: list[tuple[int, int]] | None = None
        v: dict[str, str] = {}
        for k, (letter, num) in enumerate(words):
            if letter == "G":
                key = gkey(num)
                if key not in self._g_group:
                    have = dialects.knowing_g(key)  # another control's code: say whose
                    where = (
                        f" in the {self.dialect} dialect ({', '.join(have)} have it: a "
                        "machine config of that dialect)"
                        if have
                        else ""
                    )
                    self._problem(raw, k, f"unknown G-code {gname(key)}{where}", line)
                elif gcodes is None:
                    gcodes = [(key, k)]
                else:
                    gcodes.append((key, k))
            elif letter == "M":
                key = round(float(num) * 10.0)
                if key % 10 or key // 10 not in self._known_m:
                    self._problem(raw, k, f"unknown M-code M{key / 10:g}", line)
                elif mcodes is None:
                    mcodes = [(key, k)]
                else:
                    mcodes.append((key, k))
            elif letter not in LETTERS:
                self._problem(raw, k, f"unknown address letter {letter}", line)
            elif letter in v:
                raise _lexer.word_error(
                    raw, k, f"address {letter} appears twice in the block", self.file, line
                )
            else:
                v[letter] = num
        return gcodes, mcodes, v

    def _words(
        self, raw: str, v: dict[str, str], scale: float, fscale: float, line: int, gcodes, mcodes
    ) -> None:
        """F S T D H O N P Q L R I J K and A B C: checks and recording (``fscale``: mm per unit
        of F; ``gcodes``, ``mcodes``: the block's codes, for the words G4, G10, G30, G64 and M
        codes take)."""
        st = self.state
        if "F" in v:
            self._feed(raw, v, fscale, line)
        if "S" in v:
            s = float(v["S"])
            if s < 0.0:
                raise self._fail(raw, "S", "spindle speed S must be >= 0 rpm", line)
            if s > self._spindle_max_rpm:
                self._note(
                    raw,
                    "S",
                    f"S {s:g} rpm exceeds the machine's spindle_max_rpm {self._spindle_max_rpm:g}",
                    line,
                )
            st.spindle_speed_rpm = s
        for letter in ("T", "D", "H", "O", "N"):
            if letter in v:
                n = self._whole(raw, v, letter, line)
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
            self._rotary_to = (rot[0], rot[1], rot[2])
            st.rotary_named = "".join(c for c in "ABC" if c in v or c in st.rotary_named)
        mode = st.motion
        used = ""
        if mode in (2, 3):
            used = "IJKRP" if self.rules.arc_turns_p else "IJKR"  # LinuxCNC: P turns
        elif mode >= 81:
            used = "RLPQ"
        extra = None
        for letter in "IJKRPQL":
            if letter in v and letter not in used:
                if extra is None:  # the letters the block's G and M codes take
                    extra = "".join(_G_LETTERS.get(key, "") for key, _ in gcodes or ())
                    extra += "".join(_M_LETTERS.get(key // 10, "") for key, _ in mcodes or ())
                if letter not in extra:
                    self._problem(
                        raw,
                        _lexer.find_word(raw, letter),
                        f"word {letter} is not used by any code in force (motion G{mode})",
                        line,
                    )

    def _whole(self, raw: str, v: dict[str, str], letter: str, line: int) -> int:
        """The value of a T D H O N word: a whole number 0..999999999."""
        n = float(v[letter])
        if n < 0 or n != int(n) or n > 999_999_999:
            raise self._fail(
                raw,
                letter,
                f"{letter} must be a whole number in 0..999999999, got {v[letter]}",
                line,
            )
        return int(n)

    def _feed(self, raw: str, v: dict[str, str], scale: float, line: int) -> None:
        if self.state.feed_mode == 93:
            f = float(v["F"])
            if not f > 0.0:
                raise self._fail(
                    raw,
                    "F",
                    "inverse-time feed F must be > 0 (1/min: the move takes 1/F min)",
                    line,
                )
            self._inverse_f = f
            return
        word = float(v["F"])
        f = word * scale
        if not f > 0.0:
            raise self._fail(raw, "F", "feed F must be > 0 (mm/min, or in/min under G20)", line)
        if f > self._feed_max_mm_min:
            self._note(
                raw,
                "F",
                f"feed {f:g} mm/min exceeds the machine's feed_max_mm_min "
                f"{self._feed_max_mm_min:g}",
                line,
            )
        self.state.feed_mm_min = f
        self.state.feed_word = word

    def _check_m_groups(self, raw: str, mcodes: list[tuple[int, int]], line: int) -> None:
        seen: dict[str, int] = {}
        for key, k in mcodes:
            grp = M_GROUP[key // 10]
            if grp in seen:
                raise _lexer.word_error(
                    raw,
                    k,
                    f"M{key // 10} and M{seen[grp]} are both {grp} codes and cannot share a block",
                    self.file,
                    line,
                )
            seen[grp] = key // 10
