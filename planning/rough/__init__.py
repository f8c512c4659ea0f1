"""Z-level roughing by bisection (seed 000): the part, the levels, the tool paths and their
G-code, the check of a program against the part, and plots.
"""

from planning.rough.check import check_program
from planning.rough.gcode import plan_motion, plan_program
from planning.rough.part import Part, load_part
from planning.rough.planner import RoughPlan, RoughPlanner

__all__ = [
    "Part",
    "RoughPlan",
    "RoughPlanner",
    "check_program",
    "load_part",
    "plan_motion",
    "plan_program",
]
