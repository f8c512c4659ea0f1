"""Collision-free 5-axis tool orientation (seed 002): the tool system, the orientation search,
the check between points, the machine's inverse kinematics to NC, and the whole `plan orient`
job.
"""

from planning.orient._energy import Charges, Site, energy
from planning.orient._search import _Context as SearchContext
from planning.orient._search import descend, solve_point
from planning.orient.check import verify
from planning.orient.config import load_orient
from planning.orient.job import run_orient, summary_lines
from planning.orient.kinematics import inverse, nc_program, write_cl_csv
from planning.orient.planner import energy_map, plan_orientation, require_feasible
from planning.orient.tool import ToolSystem

__all__ = [
    "Charges",
    "SearchContext",
    "Site",
    "ToolSystem",
    "descend",
    "energy",
    "energy_map",
    "inverse",
    "load_orient",
    "nc_program",
    "plan_orientation",
    "require_feasible",
    "run_orient",
    "summary_lines",
    "solve_point",
    "verify",
    "write_cl_csv",
]
