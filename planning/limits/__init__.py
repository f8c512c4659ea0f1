"""Plans that respect physics: the limits of a machine and tool (spindle power and torque, tool
deflection and chip thickness, the stability lobes), the per-block check of any program against
them, and the ``--limit`` fixes of ``plan feed`` (feed caps) and ``plan rough`` (split levels,
lower feeds); the ``plan check`` job.
"""

from planning.limits.check import CheckResult, check_motion
from planning.limits.job import check_job, coefficients, feed_limiter, rough_limiter
from planning.limits.model import Limits, LobesTable, limits_for, load_lobes

__all__ = [
    "CheckResult",
    "Limits",
    "LobesTable",
    "check_job",
    "check_motion",
    "coefficients",
    "feed_limiter",
    "limits_for",
    "load_lobes",
    "rough_limiter",
]
