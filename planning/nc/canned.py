"""Canned drilling cycles G81 / G82 / G83 expanded into rapid, feed and dwell moves (Fanuc rules).

One hole at (x, y), with the R plane ``r_mm``, the bottom ``z_mm`` and the initial level
``initial_z_mm`` (the Z where the cycle started), all absolute mm:

1. if below the R plane, rapid up to it; rapid to (x, y); rapid down to R;
2. G81: feed to the bottom. G82: feed to the bottom, dwell. G83 (peck): feed down by Q, rapid back
   to R, rapid down to ``peck_clearance_mm`` above the last depth, feed a further Q, ... until the
   bottom;
3. rapid out to the initial level (G98, never below R) or to the R plane (G99).

The interpreter (``Moves._canned`` in :mod:`planning.nc._moves`) turns the words into these
absolute parameters (G91: R is measured from the
initial level, Z from R; L repeats the hole at incremental X/Y steps).
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
