"""The modal codes of a block (private): its G codes applied to the state, one per modal group
(G80 with a motion code, group 0 codes, G61/G64 P Q), and its M codes (tool change, spindle,
coolant, stops).

:class:`Modes` extends :class:`~planning.nc._settings.Settings`.
"""

from __future__ import annotations

import math

from planning.nc import _lexer
from planning.nc._codes import MOTION_MODE, OFFSET_CODES, OFFSET_INDEX, gname
from planning.nc._settings import Settings
from planning.nc.state import CannedCycle

NAN = math.nan


class Modes(Settings):
    """G and M codes of the Interpreter (mixin)."""

    def _cutter_comp_word(self, raw: str, k: int, key: int, line: int) -> None:
        reason = (
            f"{gname(key)} cutter radius compensation is not applied: the motion is the "
            "programmed path, not the tool centre's"
        )
        if self.cutter_comp == "refuse":
            raise self._fail(
                raw, k, reason + "; give a program with the compensation resolved (the tool "
                "centre path, e.g. CAM 'computer' compensation)", line,
            )  # fmt: skip
        if not self._comp_warned:
            self._comp_warned = True
            self._note(raw, k, reason + " (said once)", line)

    def _gcodes(self, raw: str, gcodes: list[tuple[int, int]], line: int):
        """Apply the block's G codes to the state (one per modal group). Returns
        ``(explicit_motion, dwell, g53, group0, path)``: whether a group-1/G80 code was given, G4,
        G53, ``(key, word index)`` of another group-0 code (G10, G28, G92 ...) or None, and the
        key of a G61/G61.1/G64 or None (applied once the P and Q words are read)."""
        st = self.state
        explicit_motion = False
        dwell = g53 = False
        home: tuple[int, int] | None = None
        path = None
        prev_motion = st.motion
        table = self._g_group
        groups: dict[int, int] = {}
        for key, k in gcodes:
            grp = table[key]
            if grp in groups:
                other = groups[grp]
                raise _lexer.word_error(
                    raw,
                    k,
                    f"{gname(key)} and {gname(other)} are in the same modal group "
                    f"(group {grp}) and cannot share a block",
                    self.file,
                    line,
                )
            groups[grp] = key
            if grp == 9:  # G80; a G0..G3 in the same block then sets the motion mode
                g1 = groups.get(1)
                if g1 is not None and g1 >= 810:
                    raise _lexer.word_error(
                        raw, k, f"G80 and {gname(g1)} cannot share a block", self.file, line
                    )
                if g1 is None:
                    st.motion = 80
                    explicit_motion = True
            elif grp == 1:
                if 9 in groups and key >= 810:
                    raise _lexer.word_error(
                        raw, k, f"{gname(key)} and G80 cannot share a block", self.file, line
                    )
                st.motion = MOTION_MODE[key]
                explicit_motion = True
            elif grp == 0:
                if key == 40:
                    dwell = True
                elif key == 530:
                    g53 = True
                elif home is not None:
                    raise _lexer.word_error(
                        raw, k, f"{gname(key)} and {gname(home[0])} cannot share a block",
                        self.file, line,
                    )  # fmt: skip
                else:
                    home = (key, k)
            elif grp == 2:
                st.plane = key // 10
            elif grp == 6:
                st.inch = key == 200
            elif grp == 3:
                st.absolute = key == 900
            elif grp == 4:
                st.arc_absolute = key == 901
            elif grp == 5:
                # F means something else now: set it again (LinuxCNC: G94 always clears it)
                if key // 10 != st.feed_mode or (key == 940 and self.rules.g94_clears_feed):
                    st.feed_mode = key // 10
                    st.feed_mm_min = st.feed_word = NAN
            elif grp == 7:
                st.cutter_comp = key // 10
                if st.cutter_comp != 40:
                    self._cutter_comp_word(raw, k, key, line)
            elif grp == 8:
                if key == 431:  # its axis words are the offset: a setting, as G92's are
                    if home is not None:
                        raise _lexer.word_error(
                            raw, k, f"G43.1 and {gname(home[0])} both use the axis words and "
                            "cannot share a block", self.file, line,
                        )  # fmt: skip
                    home = (key, k)
                else:
                    st.tool_length = key // 10
                    self._set_tool_length_offset((0.0, 0.0, 0.0))
            elif grp == 10:
                st.retract_initial = key == 980
            elif grp == 12:  # work offsets
                st.work_offset = OFFSET_CODES[OFFSET_INDEX[key]]
                self._set_origin()
            elif grp == 13:  # G61 / G61.1 / G64
                path = key
            # 14 (G97) and 15 (G8): the only modes there are, nothing to record
        if explicit_motion and (st.motion >= 81) != (prev_motion >= 81):
            # leaving a cycle, or starting one: its initial level is taken at its first hole
            st.canned = CannedCycle()
        if home is not None and dwell:
            raise _lexer.word_error(
                raw, home[1], f"G4 and {gname(home[0])} cannot share a block", self.file, line
            )
        return explicit_motion, dwell, g53, home, path

    def _path_control(self, raw: str, v: dict[str, str], scale: float, line: int, key: int) -> None:
        """G61 / G61.1 / G64 P Q: recorded (P: blending tolerance, Q: naive-CAM tolerance; a Q
        not given is P, as in LinuxCNC)."""
        st = self.state
        st.path_control = key // 10 if key % 10 == 0 else key / 10
        if key != 640:
            return
        tol = {}
        for letter in "PQ":
            if letter in v:
                x = float(v[letter])
                if x < 0:
                    raise self._fail(raw, letter, f"G64 {letter} must be >= 0", line)
                tol[letter] = x * scale
        st.path_tolerance_mm = tol.get("P", 0.0)
        st.naive_cam_tolerance_mm = tol.get("Q", st.path_tolerance_mm)

    def _mcodes(
        self, raw: str, mcodes: list[tuple[int, int]], v: dict[str, str], line: int
    ) -> bool:
        """Apply the block's M codes (tool change, spindle, coolant, stops); True if it ends the
        program (M2/M30), which takes effect after the block's motion."""
        st = self.state
        if len(mcodes) > 1:
            self._check_m_groups(raw, mcodes, line)
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
                    raise _lexer.word_error(raw, k, "M61 needs the tool number Q", self.file, line)
                st.tool = self._whole(raw, v, "Q", line)
            # M48-M53 overrides, M62-M65 outputs: no effect on the motion
        return end
