"""NC programs for a campaign's tests, and the test block they cut.

Every program cuts the same kind of block: top face at Z = 0 (G54), X from 0 to
``block_length_mm``, Y from -``block_width_mm``/2 to +``block_width_mm``/2. A step-depth block has
steps along X whose tops sit at ``z_cut + depth_i``. The cutter always enters from -X, is lowered
to depth in the air before the block and leaves along +X, so no test plunges into material.

Programs are plain ISO text (Fanuc: O number and N words; GRBL: neither), and each is checked by
the NC parser before anything is sent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from analysis.config import EndMill, FaceMill
from analysis.forces.models import FACEMILL
from planning.nc.dialects import get as get_dialect
from planning.nc.program import format_number
from planning.stock import SteppedBlock
from rig.campaign.config import RunConditions
from rig.campaign.schema import ProgramSection

if TYPE_CHECKING:
    from analysis.config import MachineConfig
    from analysis.rules import FeedRule


@dataclass(frozen=True)
class CutProgram:
    """One generated program: text, the block it cuts, the cutting Z and the path X range, mm."""

    text: str
    block: SteppedBlock
    z_cut_mm: float
    x_start_mm: float
    x_end_mm: float
    y_path_mm: float
    cut_feed_mm_min: float


def _num(x: float) -> str:
    """A coordinate or feed word's number: 3 decimals, no trailing zeros (planning.nc style)."""
    return format_number(x, 3)


class _Writer:
    """Collects blocks; a tape program (Fanuc: the posts keep its O number) gets an O number and N
    words every block, the others (GRBL, LinuxCNC, Mach3) a title comment and no N words."""

    def __init__(self, dialect: str, number: int, title: str) -> None:
        self.dialect = dialect
        self.tape = get_dialect(dialect).post.keeps_tape
        self.lines: list[str] = []
        self._n = 0
        if self.tape:
            self.lines.append(f"O{number:04d} ({title[:60].upper()})")
        else:
            self.lines.append(f"({title[:70]})")

    def add(self, words: str) -> None:
        if self.tape:
            self._n += 10
            self.lines.append(f"N{self._n} {words}")
        else:
            self.lines.append(words)

    def text(self) -> str:
        return "\n".join(self.lines) + "\n"


def _exit_x(block_x_max: float, radius_mm: float, y_path: float, block: SteppedBlock, air: float):
    """X where the cutter centre has left all material along +X (leading half only), mm."""
    half = max(abs(block.y_min_mm - y_path), abs(block.y_max_mm - y_path))
    reach = math.sqrt(max(radius_mm**2 - half**2, 0.0)) if half < radius_mm else 0.0
    return block_x_max - reach + air


def generate_program(
    prog: ProgramSection,
    test: RunConditions,
    tool: EndMill | FaceMill,
    dialect: str,
    title: str = "",
) -> CutProgram:
    """The NC program of one test (see the module docstring for the block and path)."""
    r = tool.diameter_mm / 2
    half_w = prog.block_width_mm / 2
    length = prog.block_length_mm
    if prog.kind == "step-depth":
        depths = np.asarray(prog.step_depths_mm, dtype=float)
        z_cut = -float(depths.max())
        edges = tuple(float(x) for x in np.linspace(0.0, length, len(depths) + 1))
        tops = tuple(float(z_cut + d) for d in depths)
    else:
        z_cut = -test.depth_mm
        edges = (0.0, length)
        tops = (0.0,)
    # The path: a face mill runs with its centre offset in Y (seed 003 cuts symmetrically by
    # default); an end mill cuts a slot (width = D) or a side cut of width w on the +Y side.
    face_mill = FACEMILL.describes(tool)
    if face_mill:
        y_path = prog.offset_y_mm
        block = SteppedBlock(-half_w, half_w, edges, tops)
    else:
        width_mm = test.width_mm if test.width_mm == test.width_mm else tool.diameter_mm
        y_path = prog.offset_y_mm + (
            0.0 if width_mm >= tool.diameter_mm else half_w + r - width_mm
        )
        block = SteppedBlock(-half_w, half_w, edges, tops)
    x_start = -r - prog.approach_mm
    if face_mill:
        x_end = _exit_x(length, r, y_path, block, prog.approach_mm)
    else:
        x_end = length + r + prog.approach_mm
    feed = test.feed_mm_min
    w = _Writer(dialect, prog.program_number, title or test.name)
    w.add("G21 G90 G17 G94")
    w.add("G54")
    w.add(f"S{format_number(test.spindle_rpm, 1)} M3")
    w.add(f"G0 X{_num(x_start)} Y{_num(y_path)}")
    w.add(f"G0 Z{_num(prog.safe_z_mm)}")
    plunge = min(feed, 500.0)
    w.add(f"G1 Z{_num(z_cut)} F{_num(plunge)}")
    if prog.kind == "feed-sweep":
        feeds = prog.sweep_feeds_mm_min
        xs = np.linspace(0.0, length, len(feeds) + 1)[1:]
        xs[-1] = x_end
        w.add(f"G1 X{_num(-r)} F{_num(feeds[0])}")
        for x, f in zip(xs, feeds):
            w.add(f"G1 X{_num(float(x))} F{_num(f)}")
    else:
        w.add(f"G1 X{_num(x_end)} F{_num(feed)}")
    w.add(f"G0 Z{_num(prog.safe_z_mm)}")
    w.add("M5")
    w.add("M30")
    return CutProgram(w.text(), block, z_cut, x_start, x_end, y_path, feed)


def campaign_rule(spec: object, tool: EndMill, name: str = "campaign"):  # noqa: ANN201
    """The campaign's ``[feed_rule]`` as an ``analysis.rules.rule.FeedRule`` (reference load: a slot
    of ``reference_depth_mm`` with the campaign's tool, seed 001's load definition)."""
    from analysis.rules import derive_rule, slot_load_percent

    fr = spec.feed_rule  # type: ignore[attr-defined]
    ref = slot_load_percent(
        tool.kind, tool.diameter_mm, fr.reference_depth_mm, tool.flute_length_mm,
        tool.corner_radius_mm,
    )  # fmt: skip
    return derive_rule(
        name, fr.min_feed_mm_min, fr.base_feed_mm_min, fr.max_feed_mm_min, ref, fr.exponent,
        fr.n_bins, description=f"reference: {fr.reference_depth_mm} mm slot",
        tool=spec.campaign.tool,  # type: ignore[attr-defined]
    )  # fmt: skip


def post_process_program(
    cut: CutProgram,
    tool: EndMill,
    rule: FeedRule,
    machine: MachineConfig | None,
    min_piece_mm: float,
) -> tuple[str, dict]:
    """The load-based feed post-processor (``planning.feed.post``, seed 001) over a test program,
    on the Z-map of its block. Returns (program text, the post-processor's summary)."""
    from planning.feed import FeedPostOptions, post_process
    from planning.nc import Program, interpret

    program = Program.parse(cut.text, "<test program>")
    motion = interpret(cut.text, machine)
    res = post_process(
        program, motion, tool, rule, cut.block.to_zmap(tool), machine,
        FeedPostOptions(min_piece_mm=min_piece_mm, check_holder=False),
    )  # fmt: skip
    return res.program.text(), res.summary()
