"""Canned drilling cycles G81 / G82 / G83 expanded into rapid, feed and dwell moves.

Points are in plane coordinates ``(a, b, c)``: ``c`` is the drilling axis, the normal of the plane
(Z in G17, Y in G18, X in G19; :data:`planning.nc.arcs.PLANE_AXES`), "up" is +c. Below, x y z
stand for a b c.

:func:`drill_hole` (Fanuc and GRBL rules): one hole at (x, y), with the R plane ``r_mm``, the
bottom ``z_mm`` and the initial level ``initial_z_mm`` (the Z where the cycle started), all
absolute mm:

1. if below the R plane, rapid up to it; rapid to (x, y); rapid down to R;
2. G81: feed to the bottom. G82: feed to the bottom, dwell. G83 (peck): feed down by Q, rapid back
   to R, rapid down to ``peck_clearance_mm`` above the last depth, feed a further Q, ... until the
   bottom;
3. rapid out to the initial level (G98, never below R) or to the R plane (G99).

The interpreter (``Moves._canned`` in :mod:`planning.nc._moves`) turns the words into these
absolute parameters (G91: R is measured from the
initial level, Z from R; L repeats the hole at incremental X/Y steps).

:func:`drill_hole_linuxcnc` follows LinuxCNC's ``convert_cycle_xy`` and ``CYCLE_MACRO``: before
the holes of a block, if the initial level is below R the tool rapids straight up to R; every
hole is approached at the clearance level (R under G99, the initial level or R, whichever is
higher, under G98) — diagonally if the tool is elsewhere — except the first hole of a block
that starts above R, approached at the height the block starts at; G83 pecks from R by Q,
retracting to R and re-entering ``peck_clearance_mm`` (0.010 in) above the last depth; G82
dwells even for P0.
"""

from __future__ import annotations

from planning.nc.motion import DWELL, LINE, RAPID

NAN = float("nan")

MAX_PECKS = 10_000  # a guard against Q typos (Q0.0001) that would expand to millions of moves
Point = tuple[float, float, float]
Move = tuple[int, Point, Point, float]  # kind, start, end, dwell_s


def drill_hole(
    cycle: int,
    start: Point,
    x_mm: float,
    y_mm: float,
    r_mm: float,
    z_mm: float,
    initial_z_mm: float,
    *,
    retract_initial: bool,
    q_mm: float = 0.0,
    dwell_s: float = 0.0,
    peck_clearance_mm: float = 0.1,
) -> list[Move]:
    """The moves of one hole of cycle 81, 82 or 83, from the tool position ``start``.

    Raises ``ValueError`` with the reason when the bottom is above the R plane or a G83 peck
    depth is not positive (the interpreter adds the place).
    """
    if z_mm > r_mm:
        raise ValueError(f"hole bottom Z {z_mm:.6g} mm is above the R plane {r_mm:.6g} mm")
    if cycle == 83 and not q_mm > 0.0:
        raise ValueError(f"G83 needs a peck depth Q > 0 mm, got {q_mm:.6g}")
    if cycle == 83 and (r_mm - z_mm) / q_mm > MAX_PECKS:
        raise ValueError(
            f"G83 peck depth Q {q_mm:.6g} mm would need more than {MAX_PECKS} pecks for "
            f"{r_mm - z_mm:.6g} mm"
        )
    moves: list[Move] = []
    p = start

    def go(kind: int, q: Point, dwell: float = 0.0) -> None:
        nonlocal p
        moves.append((kind, p, q, dwell))
        p = q

    if p[2] < r_mm:
        go(RAPID, (p[0], p[1], r_mm))
    if (p[0], p[1]) != (x_mm, y_mm):
        go(RAPID, (x_mm, y_mm, p[2]))
    if p[2] != r_mm:
        go(RAPID, (x_mm, y_mm, r_mm))
    if cycle == 83:
        depth = r_mm
        while depth > z_mm:
            nxt = max(depth - q_mm, z_mm)
            if depth < r_mm:
                go(RAPID, (x_mm, y_mm, r_mm))
                go(RAPID, (x_mm, y_mm, min(depth + peck_clearance_mm, r_mm)))
            go(LINE, (x_mm, y_mm, nxt))
            depth = nxt
    else:
        go(LINE, (x_mm, y_mm, z_mm))
        if cycle == 82 and dwell_s > 0.0:
            go(DWELL, p, dwell_s)
    top = max(initial_z_mm, r_mm) if retract_initial else r_mm
    go(RAPID, (x_mm, y_mm, top))
    return moves


def drill_hole_linuxcnc(
    cycle: int,
    start: Point,
    x_mm: float,
    y_mm: float,
    r: float,
    bottom: float,
    clear: float,
    *,
    approach: float | None,
    q: float = 0.0,
    dwell_s: float = 0.0,
    peck_clearance: float = 0.254,
    scale: float = 1.0,
    offset: float = 0.0,
) -> list[Move]:
    """The moves of one hole as LinuxCNC makes them, from ``start`` (mm).

    The drilling-axis values ``r``, ``bottom``, ``clear`` (the level the hole is left at, and
    approached at), ``approach`` (the height of the approach of a block's first hole when the
    block starts above R, else None), ``q`` and ``peck_clearance`` are in program units, as
    LinuxCNC computes with them; machine mm = value * ``scale`` + ``offset``. Zero-length moves
    are left out.
    """
    if bottom > r:
        raise ValueError(f"hole bottom {bottom:.6g} is above the R plane {r:.6g}")
    if cycle == 83 and not q > 0.0:
        raise ValueError(f"G83 needs a peck depth Q > 0, got {q:.6g}")
    if cycle == 83 and (r - bottom) / q > MAX_PECKS:
        raise ValueError(
            f"G83 peck depth Q {q:.6g} would need more than {MAX_PECKS} pecks for {r - bottom:.6g}"
        )
    moves: list[Move] = []
    p = start

    def go(kind: int, c: float, dwell: float = 0.0) -> None:
        nonlocal p
        q1 = (x_mm, y_mm, c * scale + offset)
        if q1 != p or kind == DWELL:
            moves.append((kind, p, q1, dwell))
        p = q1

    if approach is not None:
        go(RAPID, approach)
        go(RAPID, r)
    else:
        go(RAPID, clear)
        if clear > r:
            go(RAPID, r)
    if cycle == 83:
        depth = r - q
        while depth > bottom:
            go(LINE, depth)
            go(RAPID, r)
            go(RAPID, depth + peck_clearance)
            depth -= q
    go(LINE, bottom)
    if cycle == 82:
        go(DWELL, bottom, dwell_s)
    go(RAPID, clear)
    return moves
