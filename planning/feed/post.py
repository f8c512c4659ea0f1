"""The feed post-processor (seed 001, CAMplus/AFC): feeds set from the predicted cutting load.

For a program, its tool, a machine and a feed rule:

1. virtual machining on a Z-map (:mod:`planning.stock.machining`) gives the volume each piece
   of each block removes (pieces no longer than half the minimum piece length);
2. the cutting load of each piece is seed 001's relative removal rate
   (:func:`analysis.rules.load.cutting_load_percent`: plunge formula for Z-only moves);
3. the rule gives each piece a feed, clamped to the rule's and the machine's [min, max] and,
   optionally, to the feed at which the predicted peak force reaches a limit;
4. a line or arc block whose feed changes along it is split at the changes into blocks no
   shorter than ``min_piece_mm`` (a piece too short to stand alone joins its neighbour and the
   slower feed wins) by :func:`planning.nc.edit.split_moves`; any other block (plunge, canned
   cycle, G53, a block that stops the program) keeps one feed, that of its most loaded piece;
5. the program is written back with only F words changed and split blocks replaced, comments,
   numbering and every other word as they were. The result is re-interpreted and its motion
   compared with the original's (splits re-joined) before anything is returned: the geometry
   never changes.

The report (:func:`planning.feed.report.write_report`): machining time before and after, the
load histogram over the rule's bins, load and feed along the path (PNG), the final stock (PNG)
and a per-block CSV.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from analysis.config import EndMill, MachineConfig
from analysis.rules import FeedRule, cutting_load_percent
from planning.errors import PlanningError
from planning.feed._write import (
    feed_runs,
    rejoin,
    splittable,
    verify_geometry,
    write_program,
)
from planning.feed.force import ForceModel
from planning.feed.result import BlockTable, FeedPostOptions, FeedPostResult, Section
from planning.nc import DWELL, Motion, Program, interpret, segment_length_mm, segment_time_s
from planning.nc.accel import accel_segment_time_s
from planning.stock import Cutter, ZMap
from planning.stock.machining import (
    Simulation,
    check_motion,
    plunge_mask,
    simulate_motion,
)
from planning.stock.plans import join_simulations


def _feed_limits(rule: FeedRule, machine: MachineConfig | None) -> tuple[float, float]:
    lo, hi = rule.min_feed_mm_min, rule.max_feed_mm_min
    if machine is not None:
        lo, hi = max(lo, machine.feed_min_mm_min), min(hi, machine.feed_max_mm_min)
    if lo > hi:
        raise PlanningError(
            f"rule '{rule.name}' feeds [{rule.min_feed_mm_min}, {rule.max_feed_mm_min}] mm/min "
            f"do not overlap machine '{machine.name if machine else ''}' feeds "
            f"[{machine.feed_min_mm_min if machine else ''}, "
            f"{machine.feed_max_mm_min if machine else ''}] mm/min"
        )
    return lo, hi


def post_process(
    program: Program,
    motion: Motion,
    tool: EndMill,
    rule: FeedRule,
    stock: ZMap,
    machine: MachineConfig | None = None,
    options: FeedPostOptions | None = None,
    progress: Callable[[int, int], None] | None = None,
    sections: list[Section] | None = None,
) -> FeedPostResult:
    """Adjust the feeds of ``program`` (interpreted as ``motion``) by predicted load.

    ``sections`` (a program that changes tools): each tool's run cut by its own tool on the
    one stock, its feeds set by its own rule, or left as programmed where its rule is None;
    default one section of ``tool`` and ``rule``. The force options need one section.

    ``stock`` is lowered in place (it ends as the machined part). Raises :class:`PlanningError`
    (before anything is written) for a program the machine cannot run, that leaves the stock,
    or a tool the Z-map cannot model. G20 programs get their F words in inch/min.
    """
    opts = options or FeedPostOptions()
    file = program.file
    sections = sections or [Section(0, len(motion), tool, rule)]
    if len(sections) > 1 and (opts.coefficients is not None or opts.feed_cap is not None):
        raise PlanningError(
            f"{file}: the force and limit options (--material, --force-limit, --limit) work on "
            "a one-tool program: run them per tool, or check the output with `cutlab plan check`"
        )
    sim = _simulate_sections(motion, machine, stock, sections, opts, file, progress)
    notes: list[str] = []
    pf = _piece_feeds(motion, sim, tool, machine, sections, opts, file, notes)
    block_feed, split = _block_feeds(program, motion, sim, pf.feed, machine, sections, opts)

    new_program, new_index = write_program(program, machine, block_feed, split)
    motion_after = interpret(
        new_program, machine, file=file, cutter_comp="refuse", probing="refuse"
    )
    verify_geometry(motion, motion_after, new_index, set(split), file)
    t_before = segment_time_s(motion, machine)  # feeds > 0: check_motion passed
    t_after = segment_time_s(motion_after, machine)
    accel_before = accel_after = None
    if machine is not None and machine.accel_mm_s2 is not None:
        acc = (machine.accel_mm_s2, machine.junction_deviation_mm)
        accel_before = float(accel_segment_time_s(motion, *acc, t_before).sum())
        accel_after = float(accel_segment_time_s(motion_after, *acc, t_after).sum())
    if sim.contacts:
        notes.append(f"{len(sim.contacts)} holder/spindle contacts with the stock (see report)")
    if len(sim.rapid_cut_segments):
        notes.append(f"{len(sim.rapid_cut_segments)} rapid moves cut material (crash on a machine)")
    piece_force = _piece_forces(pf, opts, notes)
    blocks = _block_table(motion, motion_after, sim, pf.load, pf.feed, new_index, t_before,
                          t_after, sections)  # fmt: skip
    blocks = replace(
        blocks, force_max_n=_block_max(motion.block[sim.piece_segment], piece_force, blocks.block)
    )
    return FeedPostResult(
        program=new_program,
        motion_before=motion,
        motion_after=motion_after,
        simulation=sim,
        piece_load_pct=pf.load,
        piece_feed_mm_min=pf.feed,
        piece_force_n=piece_force,
        blocks=blocks,
        time_before_s=float(t_before.sum()),
        time_after_s=float(t_after.sum()),
        split_blocks=len(split),
        rule=rule,
        stock=stock,
        notes=tuple(notes),
        accel_time_before_s=accel_before,
        accel_time_after_s=accel_after,
        sections=tuple(sections),
    )


def _simulate_sections(
    motion: Motion,
    machine: MachineConfig | None,
    stock: ZMap,
    sections: list[Section],
    opts: FeedPostOptions,
    file: str,
    progress: Callable[[int, int], None] | None,
) -> Simulation:
    """Check the motion, then cut each section's run with its own tool on the one stock."""
    widest = max((sc.tool for sc in sections), key=lambda t: t.diameter_mm)
    check_motion(motion, machine, stock, Cutter.from_tool(widest), file, opts.chord_tol_mm)
    piece_mm = opts.min_piece_mm / 2 if opts.split else math.inf
    parts = []
    for sc in sections:
        part = simulate_motion(
            stock, sc.tool, motion[sc.lo : sc.hi], chord_tol_mm=opts.chord_tol_mm,
            piece_mm=piece_mm, check_holder=opts.check_holder,
            track_depth=opts.coefficients is not None or opts.feed_cap is not None,
            progress=progress,
        )  # fmt: skip
        parts.append((sc.lo, part))
    return join_simulations(motion, parts)


@dataclass(frozen=True)
class _PieceFeeds:
    """Per piece of the simulation: load, feed (NaN off feed moves), the feed's range, and the
    force model (None without coefficients)."""

    load: NDArray[np.float64]  # % of the rule's reference load
    feed: NDArray[np.float64]  # mm/min
    lo: NDArray[np.float64]  # mm/min, the lowest feed allowed
    force: ForceModel | None


def _piece_feeds(
    motion: Motion,
    sim: Simulation,
    tool: EndMill,
    machine: MachineConfig | None,
    sections: list[Section],
    opts: FeedPostOptions,
    file: str,
    notes: list[str],
) -> _PieceFeeds:
    """Each piece's load with its section's tool and feed from its section's rule (or as
    programmed), capped by the limits and the force limit, floored to the feed step."""
    seg = sim.piece_segment
    plen = sim.piece_length_mm
    plunge = plunge_mask(sim.piece_start_mm, sim.piece_end_mm)
    load = np.zeros(len(seg))
    feed = motion.feed_mm_min[seg].astype(float)
    lo, hi = np.array(feed), np.array(feed)  # a section without a rule: clamped to itself
    fixed = np.zeros(len(seg), bool)
    for sc in sections:
        k = (seg >= sc.lo) & (seg < sc.hi)
        load[k] = cutting_load_percent(sim.piece_removed_mm3[k], plen[k], plunge[k],
                                       sc.tool.diameter_mm, sc.tool.flute_length_mm)  # fmt: skip
        if sc.rule is None:
            fixed[k] = True
            continue
        f_lo, f_hi = _feed_limits(sc.rule, machine)
        lo[k], hi[k] = f_lo, f_hi
        feed[k] = np.clip(sc.rule.feed_for(load[k]), f_lo, f_hi)
    force = None
    rpm = np.abs(motion.spindle_rpm[seg])
    if opts.spindle_rpm:
        rpm = np.where(rpm > 0, rpm, opts.spindle_rpm)
    if opts.feed_cap is not None:
        capped = np.clip(np.minimum(feed, opts.feed_cap(sim, rpm)), lo, hi)
        slower = motion.is_feed[seg] & (capped < feed)
        lost_s = float(np.sum(plen[slower] * 60.0 * (1 / capped[slower] - 1 / feed[slower])))
        if slower.any():
            notes.append(f"limits cap the feed of {int(slower.sum())} pieces: {lost_s:.1f} s "
                         "longer than the rule alone")  # fmt: skip
        feed = capped
    if opts.coefficients is not None:
        if not np.any(rpm[sim.piece_removed_mm3 > 0] > 0):
            raise PlanningError(
                f"{file}: the force prediction needs the spindle speed: the program cuts with "
                "the spindle stopped (no S/M3); give spindle_rpm"
            )
        force = ForceModel(tool, opts.coefficients, sim, rpm)
        if opts.force_limit_n is not None:
            feed = np.clip(np.minimum(feed, force.feed_cap(opts.force_limit_n)), lo, hi)
    step = opts.feed_step_mm_min
    feed = np.where(fixed, feed, np.maximum(np.floor(feed / step + 1e-9) * step, lo))
    feed = np.where(motion.is_feed[seg], feed, np.nan)
    return _PieceFeeds(load, feed, lo, force)


def _block_feeds(
    program: Program,
    motion: Motion,
    sim: Simulation,
    feed: NDArray[np.float64],
    machine: MachineConfig | None,
    sections: list[Section],
    opts: FeedPostOptions,
) -> tuple[dict[int, float], dict[int, tuple[int, list[tuple[float, float]]]]]:
    """The feed of each block (the slowest of its feed segments) and the blocks split where
    their pieces' feeds differ: ``(block -> feed, block -> (segment, [(path fraction, feed)]))``.
    ``feed`` (per piece) is set in place to what the written program runs."""
    seg = sim.piece_segment
    plen = sim.piece_length_mm
    is_feed_piece = motion.is_feed[seg]
    # Per segment: feed of its most loaded piece (the slowest), pieces kept for splitting.
    n = len(motion)
    seg_feed = np.full(n, np.inf)
    np.minimum.at(seg_feed, seg[is_feed_piece], feed[is_feed_piece])
    seg_feed[~motion.is_feed] = np.nan
    seg_feed[np.isinf(seg_feed)] = np.nan  # feed segments with no piece (zero length)
    seg_hi = motion.feed_mm_min.astype(float)  # a segment with no piece: its section's max
    for sc in sections:
        if sc.rule is not None:
            seg_hi[sc.lo : sc.hi] = _feed_limits(sc.rule, machine)[1]
    seg_feed = np.where(motion.is_feed & np.isnan(seg_feed), seg_hi, seg_feed)
    first_piece = np.searchsorted(seg, np.arange(n), side="left")
    last_piece = np.searchsorted(seg, np.arange(n), side="right")

    # Blocks: one feed each (the slowest of its feed segments) unless it is split.
    blocks_with_feed = motion.block[motion.is_feed]
    block_feed: dict[int, float] = {}
    for b, f in zip(blocks_with_feed.tolist(), seg_feed[motion.is_feed].tolist()):
        block_feed[b] = min(block_feed.get(b, math.inf), f)
    seg_count = np.bincount(motion.block, minlength=len(program))
    split: dict[int, tuple[int, list[tuple[float, float]]]] = {}
    if opts.split:
        ruled = np.zeros(n, bool)
        for sc in sections:
            ruled[sc.lo : sc.hi] = sc.rule is not None
        multi = np.nonzero(
            motion.is_feed & (motion.kind != DWELL) & (last_piece - first_piece > 1)
            & ~plunge_mask(motion.start, motion.end) & ruled
        )[0]  # fmt: skip
        for s in multi.tolist():
            a, b = first_piece[s], last_piece[s]
            f = feed[a:b]
            if np.all(f == f[0]):
                continue
            blk = int(motion.block[s])
            if seg_count[blk] != 1 or not splittable(program, blk):
                continue
            runs = feed_runs(f, plen[a:b], opts.min_piece_mm)
            if len(runs) > 1:
                # pieces of a segment are equal in length (arcs: in sweep), so run ends are
                # path fractions
                split[blk] = (s, [(1.0 if e == b - a else e / (b - a), fr) for e, fr in runs])
                for e0, (e, fr) in zip([0] + [e for e, _ in runs[:-1]], runs):
                    feed[a + e0 : a + e] = fr
            else:
                feed[a:b] = runs[0][1]
                block_feed[blk] = runs[0][1]
    # Unsplit blocks: every piece of the block runs at the block's feed.
    piece_block = motion.block[seg]
    unsplit = is_feed_piece & ~np.isin(piece_block, np.fromiter(split, int, len(split)))
    if unsplit.any():
        bf = np.array([block_feed[b] for b in piece_block[unsplit].tolist()])
        feed[unsplit] = bf
    return block_feed, split


def _piece_forces(pf: _PieceFeeds, opts: FeedPostOptions, notes: list[str]) -> NDArray[np.float64]:
    """Each piece's predicted force at its written feed (NaN without the force model)."""
    piece_force = np.full(len(pf.feed), np.nan)
    if pf.force is not None:
        piece_force = pf.force.force_n(np.where(np.isnan(pf.feed), pf.lo, pf.feed))
        if opts.force_limit_n is not None:
            over = np.nan_to_num(piece_force) > opts.force_limit_n * (1 + 1e-6)
            if over.any():
                notes.append(
                    f"{int(over.sum())} pieces exceed force_limit_n = {opts.force_limit_n} N "
                    f"even at the lowest allowed feed {np.min(pf.lo, initial=np.inf):g} mm/min"
                )
    return piece_force


def _block_max(
    piece_block: NDArray[np.int_], values: NDArray[np.float64], blocks: NDArray[np.int_]
) -> NDArray[np.float64] | None:
    """Largest value per block (NaN where none), or None when every value is NaN."""
    if np.all(np.isnan(values)):
        return None
    out = np.full(int(max(piece_block.max(), blocks.max())) + 1, np.nan)
    np.fmax.at(out, piece_block, values)
    return out[blocks]


def _block_table(
    motion: Motion,
    motion_after: Motion,
    sim: Simulation,
    load: NDArray[np.float64],
    feed: NDArray[np.float64],
    new_index: list[int],
    t_before: NDArray[np.float64],
    t_after: NDArray[np.float64],
    sections: list[Section],
) -> BlockTable:
    fm = motion.is_feed
    blocks = np.unique(motion.block[fm])
    n_blocks = int(motion.block.max()) + 1 if len(motion) else 0
    length = np.bincount(motion.block[fm], segment_length_mm(motion)[fm], n_blocks)
    removed = np.bincount(motion.block, sim.removed_mm3, n_blocks)
    plunge_blk = np.zeros(n_blocks, bool)
    plunge_blk[motion.block[plunge_mask(motion.start, motion.end) & fm]] = True
    load_blk = np.zeros(n_blocks)
    for sc in sections:  # each block with the tool that cuts it
        k = np.zeros(n_blocks, bool)
        k[motion.block[sc.lo : sc.hi]] = True
        t = sc.tool
        load_blk[k] = cutting_load_percent(
            removed[k], length[k], plunge_blk[k], t.diameter_mm, t.flute_length_mm
        )
    pb = motion.block[sim.piece_segment]
    load_max = np.zeros(n_blocks)
    np.maximum.at(load_max, pb, load)
    fb = np.full(n_blocks, np.inf)
    np.minimum.at(fb, motion.block[fm], motion.feed_mm_min[fm])
    fa = np.full(n_blocks, np.inf)
    ok = ~np.isnan(feed)
    np.minimum.at(fa, pb[ok], feed[ok])
    tb = np.bincount(motion.block, t_before, n_blocks)
    starts = np.asarray(new_index)
    src_after = np.searchsorted(starts, motion_after.block, side="right") - 1
    ta = np.bincount(src_after, t_after, n_blocks)
    nxt = np.append(starts[1:], np.iinfo(np.int64).max)
    pieces = np.minimum(nxt, int(motion_after.block.max()) + 1 if len(motion_after) else 0)
    pieces = pieces - starts
    return BlockTable(
        block=blocks.astype(np.int64),
        line=blocks.astype(np.int64) + 1,
        length_mm=length[blocks],
        removed_mm3=removed[blocks],
        load_pct=load_blk[blocks],
        load_max_pct=load_max[blocks],
        feed_before_mm_min=fb[blocks],
        feed_after_mm_min=fa[blocks],
        pieces=np.maximum(pieces[blocks], 1).astype(np.int64),
        time_before_s=tb[blocks],
        time_after_s=ta[blocks],
    )


__all__ = [
    "BlockTable",
    "FeedPostOptions",
    "FeedPostResult",
    "Section",
    "post_process",
    "rejoin",
]
