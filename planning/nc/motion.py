"""Canonical motion: the struct-of-arrays every consumer of an NC program works on.

A program interprets to ``n`` segments held in parallel numpy arrays (:class:`Motion`):

============== ============ ======= ===========================================================
field          shape        dtype   meaning
============== ============ ======= ===========================================================
kind           (n,)         int8    RAPID=0, LINE=1, ARC_CW=2, ARC_CCW=3, DWELL=4
start, end     (n, 3)       float64 tool tip X Y Z, mm, machine frame (work offset applied;
                                    offsets are zero unless given to the interpreter)
center         (n, 3)       float64 arc centre, mm; NaN unless an arc. Its in-plane coordinates
                                    are the centre; its out-of-plane coordinate equals start's
plane          (n,)         int8    17 (XY), 18 (ZX), 19 (YZ): the arc plane in force
feed_mm_min    (n,)         float64 programmed feed, mm/min; NaN for rapids and dwells
spindle_rpm    (n,)         float64 signed spindle speed, rpm: + M3, - M4, 0 stopped
tool           (n,)         int32   tool in the spindle (after M6), 0 = none
coolant        (n,)         bool    M7/M8 on
line           (n,)         int32   1-based source line
block          (n,)         int32   0-based block index (block i is line i + 1 of a file)
dwell_s        (n,)         float64 dwell time, s (0 unless DWELL)
rotary_start_  (n, 3)       float64 rotary axes A B C at the start and end of the segment, deg
deg, rotary_                        (0 where a program has no A/B/C words); they move linearly
end_deg                             along the segment
============== ============ ======= ===========================================================

``feed_mm_min`` is the programmed feed along the combined move: for a move of the rotary axes too,
the length counts millimetres and degrees together (Fanuc's convention), so a segment takes
``hypot(path length, rotary travel) / feed`` (:func:`planning.nc.stats.segment_time_s`).

Arcs: CW/CCW are seen from the positive end of the plane's normal (Z for G17, Y for G18, X for
G19). A helical arc moves the normal axis linearly. An arc whose start and end coincide in its
plane (within :data:`FULL_CIRCLE_TOL_MM`) is a full circle. Geometry helpers (sweep, length,
linearisation) are in :mod:`planning.nc.arcs`.

:class:`MotionBuilder` grows the arrays without a Python object per segment (two flat
``array.array`` buffers), which is what keeps interpretation of million-block programs flat in
memory.
"""

from __future__ import annotations

from array import array
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import pandas as pd

RAPID = 0
LINE = 1
ARC_CW = 2
ARC_CCW = 3
DWELL = 4
KIND_NAMES = ("rapid", "line", "arc_cw", "arc_ccw", "dwell")
FULL_CIRCLE_TOL_MM = 1e-6

# float fields per segment in the builder's flat buffer, then int fields
_NF = 18  # x0 y0 z0 x1 y1 z1 cx cy cz feed rpm dwell a0 b0 c0 a1 b1 c1
_NI = 6  # kind plane tool coolant line block


@dataclass(frozen=True, eq=False)
class Motion:
    """``n`` canonical motion segments as parallel arrays (see the module docstring)."""

    kind: np.ndarray
    start: np.ndarray
    end: np.ndarray
    center: np.ndarray
    plane: np.ndarray
    feed_mm_min: np.ndarray
    spindle_rpm: np.ndarray
    tool: np.ndarray
    coolant: np.ndarray
    line: np.ndarray
    block: np.ndarray
    dwell_s: np.ndarray
    rotary_start_deg: np.ndarray
    rotary_end_deg: np.ndarray

    def __len__(self) -> int:
        return int(self.kind.shape[0])

    def __getitem__(self, index: slice | np.ndarray | Sequence[int]) -> Motion:
        """The segments selected by a slice, boolean mask or index array (always a Motion)."""
        if isinstance(index, int | np.integer):
            index = slice(int(index), int(index) + 1 or None)
        return Motion(**{f.name: getattr(self, f.name)[index] for f in fields(self)})

    @staticmethod
    def empty() -> Motion:
        return MotionBuilder().build()

    @staticmethod
    def concatenate(parts: Sequence[Motion]) -> Motion:
        if not parts:
            return Motion.empty()
        return Motion(
            **{f.name: np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(Motion)}
        )

    @property
    def is_arc(self) -> np.ndarray:
        """Boolean mask (n,) of arc segments."""
        mask: np.ndarray = (self.kind == ARC_CW) | (self.kind == ARC_CCW)
        return mask

    @property
    def is_feed(self) -> np.ndarray:
        """Boolean mask (n,) of segments cut at the programmed feed (lines and arcs)."""
        return (self.kind >= LINE) & (self.kind <= ARC_CCW)

    def equals(self, other: Motion, atol_mm: float = 0.0) -> bool:
        """Same segments: integer fields equal, floats equal within ``atol_mm`` (NaN == NaN).

        ``line`` and ``block`` are compared too; use :meth:`same_path` to ignore them.
        """
        return self.same_path(other, atol_mm) and (
            np.array_equal(self.line, other.line) and np.array_equal(self.block, other.block)
        )

    def same_path(self, other: Motion, atol_mm: float = 0.0, feed_rtol: float = 0.0) -> bool:
        """Same moves (kinds, geometry, feeds, spindle, tool, coolant, dwells), any source lines."""
        if len(self) != len(other):
            return False
        for name in ("kind", "plane", "tool", "coolant"):
            if not np.array_equal(getattr(self, name), getattr(other, name)):
                return False
        for name in (
            "start", "end", "center", "dwell_s", "spindle_rpm", "rotary_start_deg", "rotary_end_deg"
        ):  # fmt: skip
            if not np.allclose(
                getattr(self, name), getattr(other, name), rtol=0, atol=atol_mm, equal_nan=True
            ):
                return False
        return bool(
            np.allclose(
                self.feed_mm_min, other.feed_mm_min, rtol=feed_rtol, atol=atol_mm, equal_nan=True
            )
        )

    def to_dataframe(self) -> pd.DataFrame:
        """A pandas DataFrame, one row per segment (I/O edge: CSV export)."""
        import pandas as pd

        return pd.DataFrame(
            {
                "line": self.line,
                "block": self.block,
                "kind": np.asarray(KIND_NAMES)[self.kind],
                "x0": self.start[:, 0],
                "y0": self.start[:, 1],
                "z0": self.start[:, 2],
                "x1": self.end[:, 0],
                "y1": self.end[:, 1],
                "z1": self.end[:, 2],
                "cx": self.center[:, 0],
                "cy": self.center[:, 1],
                "cz": self.center[:, 2],
                "plane": self.plane,
                "feed_mm_min": self.feed_mm_min,
                "spindle_rpm": self.spindle_rpm,
                "tool": self.tool,
                "coolant": self.coolant,
                "dwell_s": self.dwell_s,
                **{
                    f"{axis}{k}": arr[:, i]
                    for k, arr in ((0, self.rotary_start_deg), (1, self.rotary_end_deg))
                    for i, axis in enumerate("abc")
                },
            }
        )

    @property
    def has_rotary_travel(self) -> np.ndarray:
        """Boolean mask (n,) of segments that move a rotary axis."""
        mask: np.ndarray = np.any(self.rotary_end_deg != self.rotary_start_deg, axis=1)
        return mask


class MotionBuilder:
    """Append-only growth of segment arrays in two flat buffers (no per-segment objects).

    ``fbuf`` takes 18 floats per segment (x0 y0 z0 x1 y1 z1 cx cy cz feed rpm dwell a0 b0 c0 a1 b1
    c1) and ``ibuf``
    6 ints (kind plane tool coolant line block); :meth:`add` appends one segment, hot loops may
    ``extend`` both buffers directly in that order.
    """

    __slots__ = ("fbuf", "ibuf")

    def __init__(self) -> None:
        self.fbuf = array("d")
        self.ibuf = array("i")

    def __len__(self) -> int:
        return len(self.ibuf) // _NI

    def add(
        self,
        kind: int,
        start: Sequence[float],
        end: Sequence[float],
        center: Sequence[float] = (np.nan, np.nan, np.nan),
        *,
        plane: int = 17,
        feed_mm_min: float = np.nan,
        spindle_rpm: float = 0.0,
        tool: int = 0,
        coolant: bool = False,
        line: int = 0,
        block: int = 0,
        dwell_s: float = 0.0,
        rotary_start_deg: Sequence[float] = (0.0, 0.0, 0.0),
        rotary_end_deg: Sequence[float] | None = None,
    ) -> None:
        r1 = rotary_start_deg if rotary_end_deg is None else rotary_end_deg
        self.fbuf.extend(
            (*start, *end, *center, feed_mm_min, spindle_rpm, dwell_s, *rotary_start_deg, *r1)
        )
        self.ibuf.extend((kind, plane, tool, int(coolant), line, block))

    def build(self) -> Motion:
        f = (
            np.frombuffer(self.fbuf, dtype=np.float64).reshape(-1, _NF)
            if self.fbuf
            else (np.zeros((0, _NF)))
        )
        i = (
            np.frombuffer(self.ibuf, dtype=np.int32).reshape(-1, _NI)
            if self.ibuf
            else (np.zeros((0, _NI), np.int32))
        )
        return Motion(
            kind=i[:, 0].astype(np.int8),
            start=f[:, 0:3].copy(),
            end=f[:, 3:6].copy(),
            center=f[:, 6:9].copy(),
            plane=i[:, 1].astype(np.int8),
            feed_mm_min=f[:, 9].copy(),
            spindle_rpm=f[:, 10].copy(),
            tool=i[:, 2].copy(),
            coolant=i[:, 3].astype(bool),
            line=i[:, 4].copy(),
            block=i[:, 5].copy(),
            dwell_s=f[:, 11].copy(),
            rotary_start_deg=f[:, 12:15].copy(),
            rotary_end_deg=f[:, 15:18].copy(),
        )
