"""The modal codes of a block (private): its G codes applied to the state, one per modal group
(G80 with a motion code, group 0 codes, G61/G64 P Q), and its M codes (tool change, spindle,
coolant, stops).

:class:`Modes` is a part of :class:`~planning.nc.interpreter.Interpreter`: it works on the
interpreter's :class:`~planning.nc._context.Context`.
"""

from __future__ import annotations

import math

from planning.nc._codes import MOTION_MODE, OFFSET_CODES, OFFSET_INDEX, gname
from planning.nc._context import Codes, Context, set_origin, set_tool_length_offset
from planning.nc._words import WordRules
from planning.nc.state import CannedCycle

NAN = math.nan
# what a block's G codes give the rest of the block: explicit motion code, G4, G53, the other
# group-0 code (key, word index) and the G61/G61.1/G64 key
GCodes = tuple[bool, bool, bool, "tuple[int, int] | None", "int | None"]


class Modes:
    """G and M codes of the Interpreter (a part: works on ``ctx``; ``words`` reads their
    words)."""

    def __init__(self, ctx: Context, words: WordRules) -> None:
        self.ctx = ctx
        self.words = words

    def _cutter_comp_word(self, raw: str, k: int, key: int, line: int) -> None:
        reason = (
            f"{gname(key)} cutter radius compensation is not applied: the motion is the "
            "programmed path, not the tool centre's"
        )
        if self.ctx.cutter_comp == "refuse":
            raise self.ctx.fail(
                raw, k, reason + "; give a program with the compensation resolved (the tool "
                "centre path, e.g. CAM 'computer' compensation)", line,
            )  # fmt: skip
        if not self.ctx.comp_warned:
            self.ctx.comp_warned = True
            self.ctx.note(raw, k, reason + " (said once)", line)

    def gcodes(self, raw: str, gcodes: Codes, line: int) -> GCodes:
        """Apply the block's G codes to the state (one per modal group). Returns
        ``(explicit_motion, dwell, g53, group0, path)``: whether a group-1/G80 code was given, G4,
        G53, ``(key, word index)`` of another group-0 code (G10, G28, G92 ...) or None, and the
        key of a G61/G61.1/G64 or None (applied once the P and Q words are read)."""
        ctx = self.ctx
        st = ctx.state
        explicit_motion = False
        dwell = g53 = False
        home: tuple[int, int] | None = None
        path = None
        prev_motion = st.motion
        table = ctx.g_group
        groups: dict[int, int] = {}
        for key, k in gcodes:
            grp = table[key]
            if grp in groups:
                raise ctx.word_error(
                    raw, k, f"{gname(key)} and {gname(groups[grp])} are in the same modal group "
                    f"(group {grp}) and cannot share a block", line,
                )  # fmt: skip
            groups[grp] = key
            if grp == 9:  # G80; a G0..G3 in the same block then sets the motion mode
                g1 = groups.get(1)
                if g1 is not None and g1 >= 810:
                    raise ctx.word_error(raw, k, f"G80 and {gname(g1)} cannot share a block", line)
                if g1 is None:
                    st.motion = 80
                    explicit_motion = True
            elif grp == 1:
                if 9 in groups and key >= 810:
                    raise ctx.word_error(raw, k, f"{gname(key)} and G80 cannot share a block", line)
                st.motion = MOTION_MODE[key]
                explicit_motion = True
            elif grp == 0:
                if key == 40:
                    dwell = True
                elif key == 530:
                    g53 = True
                elif home is not None:
                    raise ctx.word_error(
                        raw, k, f"{gname(key)} and {gname(home[0])} cannot share a block", line
                    )
                else:
                    home = (key, k)
            elif grp == 8 and key == 431:  # its axis words are the offset: a setting, as G92's
                if home is not None:
                    raise ctx.word_error(
                        raw, k, f"G43.1 and {gname(home[0])} both use the axis words and cannot "
                        "share a block", line,
                    )  # fmt: skip
                home = (key, k)
            elif grp == 13:  # G61 / G61.1 / G64
                path = key
            else:
                self._set_mode(raw, grp, key, k, line)
        if explicit_motion and (st.motion >= 81) != (prev_motion >= 81):
            # leaving a cycle, or starting one: its initial level is taken at its first hole
            st.canned = CannedCycle()
        if home is not None and dwell:
            code = gname(home[0])
            raise ctx.word_error(raw, home[1], f"G4 and {code} cannot share a block", line)
        return explicit_motion, dwell, g53, home, path

    def _set_mode(self, raw: str, grp: int, key: int, k: int, line: int) -> None:
        """A code of modal group 2..12 (but G43.1) that only sets the state."""
        st = self.ctx.state
        if grp == 2:
            st.plane = key // 10
        elif grp == 6:
            st.inch = key == 200
        elif grp == 3:
            st.absolute = key == 900
        elif grp == 4:
            st.arc_absolute = key == 901
        elif grp == 5:
            # F means something else now: set it again (LinuxCNC: G94 always clears it)
            if key // 10 != st.feed_mode or (key == 940 and self.ctx.rules.g94_clears_feed):
                st.feed_mode = key // 10
                st.feed_mm_min = st.feed_word = NAN
        elif grp == 7:
            st.cutter_comp = key // 10
            if st.cutter_comp != 40:
                self._cutter_comp_word(raw, k, key, line)
        elif grp == 8:
            st.tool_length = key // 10
            set_tool_length_offset(st, (0.0, 0.0, 0.0))
        elif grp == 10:
            st.retract_initial = key == 980
        elif grp == 12:  # work offsets
            st.work_offset = OFFSET_CODES[OFFSET_INDEX[key]]
            set_origin(st)
        # 14 (G97) and 15 (G8): the only modes there are, nothing to record

    def path_control(self, raw: str, v: dict[str, str], scale: float, line: int, key: int) -> None:
        """G61 / G61.1 / G64 P Q: recorded (P: blending tolerance, Q: naive-CAM tolerance; a Q
        not given is P, as in LinuxCNC)."""
        st = self.ctx.state
        st.path_control = key // 10 if key % 10 == 0 else key / 10
        if key != 640:
            return
        tol: dict[str, float] = {}
        for letter in "PQ":
            if letter in v:
                x = float(v[letter])
                if x < 0:
                    raise self.ctx.fail(raw, letter, f"G64 {letter} must be >= 0", line)
                tol[letter] = x * scale
        st.path_tolerance_mm = tol.get("P", 0.0)
        st.naive_cam_tolerance_mm = tol.get("Q", st.path_tolerance_mm)

    def mcodes(self, raw: str, mcodes: Codes, v: dict[str, str], line: int) -> bool:
        """Apply the block's M codes (tool change, spindle, coolant, stops); True if it ends the
        program (M2/M30), which takes effect after the block's motion."""
        st = self.ctx.state
        if len(mcodes) > 1:
            self.words.check_m_groups(raw, mcodes, line)
        end = False
        for key, k in mcodes:
            m = key // 10
            if m == 6:
                st.tool = st.tool_selected
            elif m == 3:
                st.spindle_dir = 1
            elif m == 4:
                st.spindle_dir = -1
            elif m == 5:
                st.spindle_dir = 0
            elif m == 7 or m == 8:
                st.coolant = True
            elif m == 9:
                st.coolant = False
            elif m == 0 or m == 1 or m == 60:
                st.stopped = True
            elif m == 2 or m == 30:
                end = True
            elif m == 61:  # LinuxCNC: the tool in the spindle is Q, no change
                if "Q" not in v:
                    raise self.ctx.word_error(raw, k, "M61 needs the tool number Q", line)
                st.tool = self.words.whole(raw, v, "Q", line)
            # M48-M53 overrides, M62-M65 outputs: no effect on the motion
        return end
