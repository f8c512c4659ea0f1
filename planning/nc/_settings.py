"""The settings of group 0 (private): G10 (work offsets, tool table), G28.1 / G30.1, G43.1, G52,
G92 and G92.1..G92.3, each as the dialect's control sets it (no motion).

:class:`Settings` is a part of :class:`~planning.nc.interpreter.Interpreter`: it works on the
interpreter's :class:`~planning.nc._context.Context`.
"""

from __future__ import annotations

from planning.nc._codes import gname
from planning.nc._context import Context, set_origin, set_tool_length_offset


class Settings:
    """The group-0 settings of the Interpreter (a part: works on ``ctx``)."""

    def __init__(self, ctx: Context) -> None:
        self.ctx = ctx

    # ------------------------------------------------------------------ G10 / G92 / G28.1
    def setting(
        self, raw: str, v: dict[str, str], scale: float, line: int, key: int, k: int
    ) -> None:
        """The codes that set something from the block's words (no motion): G10, G28.1 / G30.1,
        G43.1, G52, G92, G92.1 / G92.2 / G92.3."""
        st = self.ctx.state
        code = gname(key)
        if key == 100:
            self._g10(raw, v, scale, line, k)
            return
        axes = [a for a in range(3) if "XYZ"[a] in v]
        rot = [c for c in "ABC" if c in v]
        if key == 431:
            self._g43_1(raw, v, scale, line, k, axes, rot)
            return
        if key in (281, 301, 921, 922, 923):
            if axes or rot:
                raise self.ctx.fail(
                    raw, ("XYZ"[axes[0]] if axes else rot[0]), f"{code} takes no axis words", line
                )
            if key == 281:
                st.reference_mm = st.position_mm
                st.reference_rotary_deg = st.rotary_deg
            elif key == 301:
                st.second_reference_mm = st.position_mm
                st.second_reference_rotary_deg = st.rotary_deg
            elif key == 921:
                st.g92_offset_mm = st.g92_saved_mm = (0.0, 0.0, 0.0)
            elif key == 922:
                st.g92_offset_mm = (0.0, 0.0, 0.0)
            else:
                st.g92_offset_mm = st.g92_saved_mm
            set_origin(self.ctx.state)
            return
        # G92 / G52
        if not axes and not rot:
            raise self.ctx.fail(raw, k, f"{code} needs at least one axis word", line)
        for c in rot:  # the rotary axes have no offsets here: only what leaves them as they are
            now = st.rotary_deg["ABC".index(c)]
            if float(v[c]) != (now if key == 920 else 0.0):
                raise self.ctx.fail(raw, c, f"{code}: rotary axis offsets are not supported", line)
        off = list(st.g92_offset_mm)
        work = st.work_offsets_mm[st.work_offset_index]
        for a in axes:
            val = float(v["XYZ"[a]]) * scale
            off[a] = st.position_mm[a] - work[a] - val if key == 920 else val
        st.g92_offset_mm = st.g92_saved_mm = (off[0], off[1], off[2])
        set_origin(self.ctx.state)

    def _g10(self, raw: str, v: dict[str, str], scale: float, line: int, k: int) -> None:
        """G10 L2 / L20 (work offsets) and L1 / L10 / L11 (tool table)."""
        ctx = self.ctx
        if "L" not in v:
            raise ctx.fail(raw, k, "G10 needs L (L2/L20 work offset, L1/L10 tool table)", line)
        lf = float(v["L"])
        ell = round(lf)
        d = ctx.rules
        known = d.g10_l
        if ell != lf or ell not in known:
            raise ctx.fail(
                raw, "L", f"G10 L{v['L']} is not one of L{', L'.join(map(str, known))} "
                f"({ctx.dialect})", line,
            )  # fmt: skip
        if ell == 0:  # LinuxCNC: reload the tool table (from the file: nothing known here)
            return
        if "P" not in v:
            raise ctx.fail(raw, k, f"G10 L{ell} needs P", line)
        pf = float(v["P"])
        p = round(pf)
        if abs(pf - p) > 0.0002:
            raise ctx.fail(raw, "P", f"G10 P must be a whole number, got {v['P']}", line)
        axes = [a for a in range(3) if "XYZ"[a] in v]
        if ell in (2, 20):
            self._g10_work_offset(raw, v, scale, line, ell, p, axes)
        elif d.g10_tool_table:  # else L1 / L10..L13: Fanuc's tool offset memories (not modelled)
            self._g10_tool_table(raw, v, scale, line, k, ell, p, axes)

    def _g10_work_offset(
        self, raw: str, v: dict[str, str], scale: float, line: int, ell: int, p: int,
        axes: list[int],
    ) -> None:  # fmt: skip
        """G10 L2 / L20 Pp: work offset p (P0: the active one) from the axis words."""
        st = self.ctx.state
        low, top = self.ctx.rules.g10_p_range
        if not low <= p <= top:
            why = " (the external offset P0 is not supported)" if low > 0 and p == 0 else ""
            raise self.ctx.fail(raw, "P", f"G10 L{ell} P must be in 0..{top}, got {p}{why}", line)
        for c in "IJ":
            if c in v:
                raise self.ctx.fail(raw, c, f"G10 L{ell} takes no {c} word", line)
        if "R" in v and float(v["R"]) != 0.0:
            raise self.ctx.fail(
                raw, "R", "G10 L2 R: rotated coordinate systems are not supported", line
            )
        for c in "ABC":
            if c in v and float(v[c]) != (st.rotary_deg["ABC".index(c)] if ell == 20 else 0.0):
                raise self.ctx.fail(raw, c, "offsets of the rotary axes are not supported", line)
        idx = st.work_offset_index if p == 0 else p - 1
        off = list(st.work_offsets_mm[idx])
        for a in axes:
            val = float(v["XYZ"[a]]) * scale
            if ell == 20:  # the current position reads val in system idx
                off[a] = st.position_mm[a] - st.g92_offset_mm[a] - val
            elif self.ctx.rules.g10_incremental and not st.absolute:
                off[a] += val
            else:
                off[a] = val
        table = list(st.work_offsets_mm)
        table[idx] = (off[0], off[1], off[2])
        st.work_offsets_mm = tuple(table)
        st.work_offsets_set = st.work_offsets_set | {idx}
        if idx == st.work_offset_index:
            set_origin(st)

    def _g10_tool_table(
        self, raw: str, v: dict[str, str], scale: float, line: int, k: int, ell: int, p: int,
        axes: list[int],
    ) -> None:  # fmt: skip
        """LinuxCNC's G10 L1 (direct), L10 (the current position reads the values), L11 (in
        G59.3): tool p's entry of the tool table."""
        st = self.ctx.state
        if p < 1:
            raise self.ctx.fail(raw, "P", f"G10 L{ell} P (tool number) must be 1 or more", line)
        if not axes and not any(c in v for c in "ABCRQIJ"):
            raise self.ctx.fail(raw, k, f"G10 L{ell} without offsets has no effect", line)
        entry = list(st.tool_table.get(p, (0.0, 0.0, 0.0, 0.0)))
        if ell == 1:
            for a in axes:
                entry[a] = float(v["XYZ"[a]]) * scale
        else:
            tlo = 0.0
            if st.tool_length == 43:
                tlo = st.tool_table.get(st.tool_length_h or st.tool, (0.0, 0.0, 0.0, 0.0))[2]
            elif st.tool_length == 431:
                tlo = st.tool_length_offset_mm[2]
            work = st.work_offsets_mm[8 if ell == 11 else st.work_offset_index]
            g92 = (0.0, 0.0, 0.0) if ell == 11 else st.g92_offset_mm
            for a in axes:
                here = st.position_mm[a] + (tlo if a == 2 else 0.0) - work[a] - g92[a]
                entry[a] = here - float(v["XYZ"[a]]) * scale
        if "R" in v:
            entry[3] = float(v["R"]) * scale
        table = dict(st.tool_table)
        table[p] = (entry[0], entry[1], entry[2], entry[3])
        st.tool_table = table

    def _g43_1(
        self, raw: str, v: dict[str, str], scale: float, line: int, k: int, axes: list[int],
        rot: list[str],
    ) -> None:  # fmt: skip
        """G43.1: the dynamic tool length offset is the axis words (absolute under G91 too; none:
        zero, LinuxCNC; GRBL takes Z and only Z, its error 37)."""
        if rot:
            raise self.ctx.fail(raw, rot[0], "G43.1: rotary axis offsets are not supported", line)
        if self.ctx.rules.g43_1_z_only and axes != [2]:
            letter = next((L for L in "XY" if L in v), None)
            raise self.ctx.fail(
                raw, letter or k, "G43.1 on GRBL takes Z and only Z (error:37)", line
            )
        x, y, z = (float(v["XYZ"[a]]) * scale if a in axes else 0.0 for a in range(3))
        self.ctx.state.tool_length = 431
        set_tool_length_offset(self.ctx.state, (x, y, z))
