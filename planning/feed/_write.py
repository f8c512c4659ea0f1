"""Writing the feed post-processor's answer back into the program (see :mod:`planning.feed.post`).

Pieces of equal feed are grouped into runs no shorter than the minimum piece length
(:func:`feed_runs`); F words are rewritten only where the modal feed must change and split blocks
are cut by :func:`planning.nc.edit.split_moves` (:func:`write_program`); the result is checked to
move exactly like the source once its splits are re-joined (:func:`rejoin`,
:func:`verify_geometry`).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from analysis.config import MachineConfig
from planning.errors import PlanningError
from planning.nc import INCH_MM, Interpreter, Motion, Program
from planning.nc.edit import split_moves

_GEOMETRY_TOL_MM = 1e-3  # written coordinates are rounded to the program's decimals (>= 3)


def feed_runs(
    feeds: NDArray[np.float64], lengths: NDArray[np.float64], min_piece_mm: float
) -> list[tuple[int, float]]:
    """Group pieces into runs of equal feed, each >= min_piece_mm long (the short ones join the
    neighbour with the lower feed, which then applies to both); returns (end piece, feed) pairs.
    """
    runs: list[list[float]] = []  # [end index (exclusive), feed, length]
    for i, (f, ln) in enumerate(zip(feeds.tolist(), lengths.tolist())):
        if runs and runs[-1][1] == f:
            runs[-1][0], runs[-1][2] = i + 1, runs[-1][2] + ln
        else:
            runs.append([i + 1, f, ln])
    while len(runs) > 1:
        short = [k for k, r in enumerate(runs) if r[2] < min_piece_mm - 1e-9]
        if not short:
            break
        k = min(short, key=lambda j: runs[j][2])
        # join the neighbour with the lower feed (the slower feed is the safe one)
        if k == 0:
            j = 1
        elif k == len(runs) - 1:
            j = k - 1
        else:
            j = k - 1 if runs[k - 1][1] <= runs[k + 1][1] else k + 1
        a, b = sorted((k, j))
        merged = [runs[b][0], min(runs[a][1], runs[b][1]), runs[a][2] + runs[b][2]]
        runs[a : b + 1] = [merged]
        # neighbours that now share a feed become one run
        out: list[list[float]] = []
        for r in runs:
            if out and out[-1][1] == r[1]:
                out[-1][0], out[-1][2] = r[0], out[-1][2] + r[2]
            else:
                out.append(r)
        runs = out
    return [(int(r[0]), float(r[1])) for r in runs]


def splittable(program: Program, block: int) -> bool:
    """Whether planning.nc.edit can split the block (no G53, no program stop or end)."""
    for t in program.words(block):
        if t.letter == "G" and float(t.number) == 53:
            return False
        if t.letter == "M" and float(t.number) in (0, 1, 2, 30):
            return False
    return True


def write_program(
    program: Program,
    machine: MachineConfig | None,
    block_feed: dict[int, float],
    split: dict[int, tuple[int, list[tuple[float, float]]]],
) -> tuple[Program, list[int]]:
    """The adjusted program and, per source block, the index of its first output block.

    F words are written only where the modal feed must change (every F word of the source is
    kept or rewritten, none is left stale); split blocks are cut by
    :func:`planning.nc.edit.split_moves`, each piece with its F, the last piece's feed staying
    modal (the following blocks are written knowing that).
    """
    out = Program(list(program.lines), program.file, program.newline, program.final_newline)
    out._style = program.style  # noqa: SLF001 - same number style as the source
    lines = program.lines
    with_f = {i for i, raw in enumerate(lines) if "F" in raw or "f" in raw}
    fmt = out.style.format
    scale = _feed_scale(program, machine)  # per block: mm per program unit of its F word
    modal = math.nan  # mm/min, as the control reads the F words written so far
    for b in sorted(with_f | set(block_feed)):
        want = block_feed.get(b)
        if b in split:
            want = split[b][1][-1][1]  # split_moves writes each piece's F; the last stays modal
        txt = out.get_word(b, "F") if b in with_f else None
        if want is None:  # an F word on a block without feed moves sets the modal feed
            if txt is not None:
                modal = float(txt) * scale[b]
            continue
        want_txt = fmt(want / scale[b], "F")
        want_mm = float(want_txt) * scale[b]
        if txt is not None or want_mm != modal or b in split:
            if txt is None or float(txt) != float(want_txt):
                out.set_word(b, "F", want_txt)
            modal = want_mm
    if not split:
        return out, list(range(len(lines)))
    plan = {seg: runs for seg, runs in split.values()}
    result = split_moves(out, plan, machine, restore_feed=False)
    new_index, k = [], 0
    for b in range(len(lines)):
        new_index.append(k)
        k += len(split[b][1]) if b in split else 1
    if k != len(result.lines):
        raise PlanningError(
            f"{program.file}: splitting gave {len(result.lines)} blocks, expected {k} (internal)"
        )
    return result, new_index


def _feed_scale(program: Program, machine: MachineConfig | None) -> NDArray[np.float64]:
    """mm per unit of each block's F word: 25.4 under G20 (a unit word applies to its own
    block's words), else 1. Only G20 programs are interpreted for it."""
    scale = np.ones(len(program.lines))
    if not any("20" in raw for raw in program.lines):
        return scale
    it = Interpreter(machine, strict=False, file=program.file)
    for b, raw in enumerate(program.lines):
        it.execute(raw, line=b + 1, block=b)
        scale[b] = INCH_MM if it.state.inch else 1.0
    return scale


def rejoin(motion_after: Motion, new_index: list[int], split_blocks: set[int]) -> Motion:
    """Undo the splits: consecutive segments from one split source block become one segment.

    ``new_index[i]`` is the first output block of source block ``i``; the returned motion has
    the source block numbers, and feeds of the first piece.
    """
    starts = np.asarray(new_index)
    src = np.searchsorted(starts, motion_after.block, side="right") - 1
    is_split = np.isin(src, np.fromiter(split_blocks, int, len(split_blocks)))
    # a segment continues the previous one when both come from the same split block
    cont = np.zeros(len(motion_after), bool)
    cont[1:] = is_split[1:] & (src[1:] == src[:-1])
    keep = ~cont
    groups = np.cumsum(keep) - 1
    last = np.zeros(keep.sum(), np.int64)
    last[groups] = np.arange(len(motion_after))
    m = motion_after[keep]
    end = m.end.copy()
    end[:] = motion_after.end[last]
    return replace(m, end=end, block=src[keep].astype(np.int32))


def verify_geometry(
    before: Motion, after: Motion, new_index: list[int], split: set[int], file: str
) -> None:
    """The adjusted program must move exactly like the original but for feed."""
    joined = rejoin(after, new_index, split)
    ok = len(joined) == len(before)
    if ok:
        ok = (
            np.array_equal(joined.kind, before.kind)
            and np.array_equal(joined.block, before.block)
            and np.allclose(joined.start, before.start, atol=_GEOMETRY_TOL_MM, rtol=0)
            and np.allclose(joined.end, before.end, atol=_GEOMETRY_TOL_MM, rtol=0)
            and np.allclose(
                joined.center, before.center, atol=_GEOMETRY_TOL_MM, rtol=0, equal_nan=True
            )
        )
    if not ok:
        raise PlanningError(
            f"{file}: the adjusted program would not move like the original (internal check "
            "failed); nothing written"
        )


def cap_feeds(
    program: Program, motion: Motion, machine: MachineConfig | None, caps: dict[int, float]
) -> Program:
    """``program`` (interpreted as ``motion``) with each block of ``caps`` run no faster than
    its cap, mm/min; only F words change (the modal feed of the blocks after is kept)."""
    fm = motion.is_feed
    block_feed: dict[int, float] = {}
    for b, f in zip(motion.block[fm].tolist(), motion.feed_mm_min[fm].tolist()):
        block_feed[b] = min(block_feed.get(b, math.inf), f)
    for b, cap in caps.items():
        if b in block_feed:
            block_feed[b] = min(block_feed[b], cap)
    return write_program(program, machine, block_feed, {})[0]
