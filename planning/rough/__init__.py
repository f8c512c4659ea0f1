"""Z-level roughing by bisection (seed 000): the part, the levels, the tool paths and their
G-code, the check of a program against the part, plots, and the whole `plan rough` job.
"""

from planning.rough._arcs import fit_arcs, sample_path
from planning.rough.check import check_program
from planning.rough.gcode import plan_motion, plan_program
from planning.rough.job import comparison_pct, run_rough, shorter_pct
from planning.rough.part import Part, load_part
from planning.rough.planner import RoughPlan, RoughPlanner

__all__ = [
    "Part",
    "RoughPlan",
    "RoughPlanner",
    "check_program",
    "comparison_pct",
    "fit_arcs",
    "load_part",
    "plan_motion",
    "plan_program",
    "run_rough",
    "sample_path",
    "shorter_pct",
]
