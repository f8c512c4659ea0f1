"""What the simulated rig reads of a campaign and of one planned run: the fields, named as
Protocols. rig.campaign (above rig.sim) hands in its ``Campaign`` and ``PlannedRun``, which have
them; rig.sim does not import rig.campaign."""

from __future__ import annotations

from typing import Protocol

from analysis.config import EndMill, FaceMill, MachineConfig, Material, RigConfig, ToolMode
from planning.stock import SteppedBlock

__all__ = ["SimCampaign", "SimCut", "SimDaqSettings", "SimPlan", "SimSettings", "SimSpec"]


class SimSettings(Protocol):
    """The campaign's ``[sim]`` table: pace, disturbances, injected faults, the twin's model."""

    @property
    def speed(self) -> float: ...  # simulated s per wall s
    @property
    def protocol(self) -> str | None: ...  # None: the machine's dialect
    @property
    def noise_n(self) -> float: ...
    @property
    def drift_n_s(self) -> float: ...
    @property
    def hum_n(self) -> float: ...
    @property
    def hum_hz(self) -> float: ...
    @property
    def seed(self) -> int: ...
    @property
    def link_timeout_s(self) -> float: ...
    @property
    def sim_controller_stall_after_block(self) -> int | None: ...
    @property
    def sim_alarm_at_block(self) -> int | None: ...
    @property
    def sim_daq_overflow_at_s(self) -> float | None: ...
    @property
    def sim_interlock_at_s(self) -> float | None: ...
    @property
    def sim_fault_run(self) -> int: ...
    @property
    def tool_modes(self) -> tuple[ToolMode, ...] | None: ...
    @property
    def tool_max_chip_mm(self) -> float | None: ...
    @property
    def force_model(self) -> str: ...


class SimDaqSettings(Protocol):
    """The campaign's ``[daq]`` overrides of the rig's DAQ (None: the rig's)."""

    @property
    def rate_hz(self) -> float | None: ...
    @property
    def read_interval_s(self) -> float | None: ...


class SimSpec(Protocol):
    """The campaign file's tables the simulated rig reads."""

    @property
    def sim(self) -> SimSettings: ...
    @property
    def daq(self) -> SimDaqSettings: ...


class SimCampaign(Protocol):
    """A loaded campaign as the simulated rig reads it (rig.campaign's ``Campaign``)."""

    @property
    def spec(self) -> SimSpec: ...
    @property
    def rig(self) -> RigConfig: ...
    @property
    def machine(self) -> MachineConfig: ...
    @property
    def tool(self) -> EndMill | FaceMill: ...
    @property
    def material(self) -> Material: ...


class SimCut(Protocol):
    """A planned run's cut: the block of stock it cuts."""

    @property
    def block(self) -> SteppedBlock: ...


class SimPlan(Protocol):
    """A planned run as the simulated rig reads it (rig.campaign's ``PlannedRun``)."""

    @property
    def cut(self) -> SimCut: ...
