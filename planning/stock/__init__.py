"""Stock and virtual machining (seed 001): the Z-map, starting stocks, the stepped test block,
simulated machining of programs and operation plans, and the stock's picture.
"""

from planning.stock import _kernels as kernels  # the swept envelopes, exact and sampled
from planning.stock import _numba as compiled  # the compiled kernels: AVAILABLE, warm_up
from planning.stock._numba import MAX_ARCS
from planning.stock.block import SteppedBlock
from planning.stock.machining import (
    ARC_STEP_RAD,
    Simulation,
    check_motion,
    default_stock,
    load_stock,
    simulate_motion,
)
from planning.stock.plans import Operation, OperationPlan, load_plan
from planning.stock.plot import save_stock_png
from planning.stock.zmap import Cutter, ZMap

__all__ = [
    "ARC_STEP_RAD",
    "MAX_ARCS",
    "Cutter",
    "Operation",
    "OperationPlan",
    "Simulation",
    "SteppedBlock",
    "ZMap",
    "check_motion",
    "compiled",
    "default_stock",
    "kernels",
    "load_plan",
    "load_stock",
    "save_stock_png",
    "simulate_motion",
]
