"""What the adaptive loop reads of a campaign and of one test: the fields, named as Protocols.
rig.campaign (above rig.adaptive) hands in its ``Campaign`` and ``RunConditions``, which have them;
rig.adaptive does not import rig.campaign. A field the loop starts reading is added here."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:  # annotations only: importing rig.adaptive loads neither
    from analysis.chatter import ChatterSettings
    from analysis.config import EndMill, FaceMill, MachineConfig, Material, RigConfig, ToolMode
    from rig.daq import Daq

__all__ = [
    "AdaptiveCampaign",
    "AdaptiveSpec",
    "AdaptiveTable",
    "AdaptiveTest",
    "LobeCampaign",
    "LobeTest",
    "LoopSession",
]


class AdaptiveTable(Protocol):
    """The campaign's ``[adaptive]`` table."""

    @property
    def mode(self) -> str: ...  # feed, spindle or both
    @property
    def groups(self) -> tuple[str, ...]: ...  # empty: all
    @property
    def target_force_n(self) -> float | None: ...
    @property
    def max_force_n(self) -> float | None: ...
    @property
    def dead_band_pct(self) -> float: ...
    @property
    def slew_up_pct(self) -> int: ...
    @property
    def slew_down_pct(self) -> int: ...
    @property
    def settle_revs(self) -> int: ...
    @property
    def air_force_n(self) -> float: ...
    @property
    def stall_revs(self) -> float: ...
    @property
    def chatter_revs(self) -> int: ...
    @property
    def min_pct(self) -> int: ...
    @property
    def max_pct(self) -> int: ...
    @property
    def sim_signal_loss_at_s(self) -> float | None: ...


class _Rig(Protocol):
    @property
    def rig(self) -> str: ...  # "sim" or "real"


class _Sim(Protocol):
    @property
    def protocol(self) -> str | None: ...
    @property
    def tool_modes(self) -> tuple[ToolMode, ...] | None: ...


class _Daq(Protocol):
    @property
    def rate_hz(self) -> float | None: ...
    @property
    def rest_s(self) -> float: ...


class _Suspenders(Protocol):
    @property
    def force_limit_n(self) -> float | None: ...


class _Chatter(Protocol):
    def settings(self) -> ChatterSettings: ...


class _FeedRule(Protocol):
    @property
    def reference_depth_mm(self) -> float: ...
    @property
    def base_feed_mm_min(self) -> float: ...


class _Group(Protocol):
    @property
    def group(self) -> str: ...


class AdaptiveSpec(Protocol):
    """The campaign file's tables the loop reads."""

    @property
    def campaign(self) -> _Rig: ...
    @property
    def sim(self) -> _Sim: ...
    @property
    def daq(self) -> _Daq: ...
    @property
    def suspenders(self) -> _Suspenders: ...
    @property
    def chatter(self) -> _Chatter: ...
    @property
    def feed_rule(self) -> _FeedRule | None: ...
    @property
    def adaptive(self) -> AdaptiveTable | None: ...
    @property
    def matrix(self) -> Sequence[_Group]: ...
    @property
    def tests(self) -> Sequence[_Group]: ...


class LobeTest(Protocol):
    """A test as the lobes read it: the spindle speed and the width of cut."""

    @property
    def spindle_rpm(self) -> float: ...
    @property
    def width_mm(self) -> float: ...


class AdaptiveTest(LobeTest, Protocol):
    """A test of the matrix (rig.campaign's ``RunConditions``) as the loop reads it."""

    @property
    def group(self) -> str: ...
    @property
    def depth_mm(self) -> float: ...


class LobeCampaign(Protocol):
    """A campaign as the lobes read it: the tool, its modes, the material, the teeth."""

    @property
    def spec(self) -> AdaptiveSpec: ...
    @property
    def tool(self) -> EndMill | FaceMill: ...
    @property
    def material(self) -> Material: ...
    @property
    def teeth(self) -> int: ...


class AdaptiveCampaign(LobeCampaign, Protocol):
    """A loaded campaign (rig.campaign's ``Campaign``) as the loop reads it."""

    @property
    def name(self) -> str: ...
    @property
    def path(self) -> Path: ...
    @property
    def machine(self) -> MachineConfig: ...
    @property
    def rig(self) -> RigConfig: ...
    @property
    def tests(self) -> Sequence[AdaptiveTest]: ...


class LoopSession(Protocol):
    """A rig session the loop goes around (rig.campaign's ``RigSession``): its DAQ and clock."""

    @property
    def daq(self) -> Daq: ...
    @property
    def clock(self) -> Callable[[], float]: ...
