"""planning.nc — the NC language: parse, interpret to canonical motion, edit and write programs.

Quick tour::

    from planning.nc import Program, interpret, interpret_file, motion_stats, Interpreter

    prog = Program.read("data/programs/demo-part.nc")   # layout-keeping text (editable)
    motion = interpret(prog)                             # -> Motion (struct of numpy arrays)
    stats = motion_stats(motion, machine)                # time, lengths, bbox

    motion = interpret_file("big.nc")                    # streaming, for huge programs

    it = Interpreter(machine, strict=False)              # one block at a time (controllers)
    seg = it.execute("G1 X10 F300"); snapshot = it.state.copy(); it.warnings

    state = state_at_block(prog, 120)                    # DNC restart from block 120
    blocks = restart_preamble(state)

    prog.set_word(12, "F", 250)                          # edits touch only those words
    prog.replace_blocks({40: [{"X": 5, "F": 200}, {"X": 10, "F": 300}]})
    prog.write("out.nc")

    from planning.nc.edit import split_moves             # feed post-processing
    new = split_moves(prog, {7: [(0.5, 400.0), (1.0, 650.0)]})   # segment 7: two feeds

    Conventions: block i is line i + 1 of the text (blank, comment and % lines are empty
    blocks); the interpreter starts at X0 Y0 Z0 unless given a state; Motion is in mm, mm/min.

    lin = linearize(motion, chord_tol_mm=0.005)          # arcs -> chords, lin.source maps back
    motion_to_program(motion).write("path.nc")           # motion -> NC

Modules: :mod:`~planning.nc.motion` (Motion, kinds), :mod:`~planning.nc.interpreter`
(Interpreter), :mod:`~planning.nc.run` (whole programs, state at block N),
:mod:`~planning.nc.state` (ModalState), :mod:`~planning.nc.program` (Program, editing),
:mod:`~planning.nc.edit` (feed edits, split moves), :mod:`~planning.nc.writer`,
:mod:`~planning.nc.arcs`, :mod:`~planning.nc.canned`, :mod:`~planning.nc.stats`,
:mod:`~planning.nc.restart`, :mod:`~planning.nc.plot`, :mod:`~planning.nc.check` (a program
file checked as ``cutlab nc`` shows it), :mod:`~planning.nc.errors`, :mod:`~planning.nc.dialects`
(one Dialect per controller: ``DIALECTS`` its names, ``get_dialect(name)`` its rules).
"""

from importlib import import_module
from typing import Any

# Loaded on first use (PEP 562): `cutlab nc check` needs the interpreter and the statistics, not
# the program editor, the dialects, the writers or the plots.
_LAZY = {
    "planning.nc._codes": ("INCH_MM",),
    "planning.nc._fast": ("FAST_MIN_RUN", "present_mask"),
    "planning.nc._lexer": ("block_words", "line_error", "tokenize"),
    "planning.nc.arcs": ("Linearized", "arc_radius_mm", "arc_sweep_rad", "bounding_box",
                         "linearize", "segment_length_mm", "segment_travel"),
    "planning.nc.check": ("CheckedProgram", "check_program", "write_motions_csv"),
    "planning.nc.dialect": ("DialectProblem", "check_dialect"),
    "planning.nc.dialects": ("DIALECTS", "Dialect", "get_dialect"),
    "planning.nc.errors": ("NCError", "NCWarning"),
    "planning.nc.interpreter": ("Interpreter",),
    "planning.nc.motion": ("ARC_CCW", "ARC_CW", "DWELL", "FULL_CIRCLE_TOL_MM", "KIND_NAMES",
                           "LINE", "RAPID", "Motion", "MotionBuilder"),
    "planning.nc.output": ("for_dialect",),
    "planning.nc.program": ("NumberStyle", "Program"),
    "planning.nc.restart": ("restart_preamble",),
    "planning.nc.run": ("MAX_LINE_CHARS", "interpret", "interpret_file", "iter_motion_chunks",
                        "state_at_block"),
    "planning.nc.state": ("CannedCycle", "ModalState"),
    "planning.nc.stats": ("MotionStats", "StreamStats", "motion_stats", "segment_time_s"),
    "planning.nc.table": ("write_motion_csv",),
    "planning.nc.writer": ("motion_to_program",),
}  # fmt: skip
_WHERE = {name: module for module, names in _LAZY.items() for name in names}


def __getattr__(name: str) -> Any:
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(_WHERE[name]), name)
    globals()[name] = value
    return value


__all__ = [
    "ARC_CCW",
    "ARC_CW",
    "CannedCycle",
    "CheckedProgram",
    "DIALECTS",
    "DWELL",
    "Dialect",
    "DialectProblem",
    "FAST_MIN_RUN",
    "FULL_CIRCLE_TOL_MM",
    "INCH_MM",
    "Interpreter",
    "KIND_NAMES",
    "LINE",
    "Linearized",
    "MAX_LINE_CHARS",
    "ModalState",
    "Motion",
    "MotionBuilder",
    "MotionStats",
    "NCError",
    "NCWarning",
    "NumberStyle",
    "Program",
    "RAPID",
    "StreamStats",
    "arc_radius_mm",
    "arc_sweep_rad",
    "block_words",
    "bounding_box",
    "check_dialect",
    "check_program",
    "for_dialect",
    "get_dialect",
    "interpret",
    "interpret_file",
    "iter_motion_chunks",
    "line_error",
    "linearize",
    "motion_stats",
    "motion_to_program",
    "present_mask",
    "restart_preamble",
    "segment_length_mm",
    "segment_time_s",
    "segment_travel",
    "state_at_block",
    "tokenize",
    "write_motion_csv",
    "write_motions_csv",
]
