"""The simulated rig, behind the same interfaces as the hardware: the clock, the DAQ, the machine
(cutting physics and the dynamometer), the Fanuc and GRBL controllers on pseudo-terminals, and
the session that ties them together for a campaign; the tool's tap test (:mod:`rig.sim.tap`).
"""

from rig.sim.campaign_view import SimCampaign, SimPlan
from rig.sim.clock import SimClock
from rig.sim.controllers import (
    ControllerSummary,
    controller_class,
    controller_summary,
    run_controller,
    sim_controller,
)
from rig.sim.daq import SimDaq
from rig.sim.fanuc import SimFanuc
from rig.sim.grbl import SimGrbl
from rig.sim.machine import SimMachine
from rig.sim.session import sim_session
from rig.sim.tap import tap_test_record

__all__ = [
    "ControllerSummary",
    "SimCampaign",
    "SimClock",
    "SimDaq",
    "SimFanuc",
    "SimGrbl",
    "SimMachine",
    "SimPlan",
    "controller_class",
    "controller_summary",
    "run_controller",
    "sim_controller",
    "sim_session",
    "tap_test_record",
]
