"""The live console's JSON-shaped results, keys and value types spelled out: what the server
sends the page (the cut and its lobes, the spectrum's peak, the logger's health, the machine's
state, the tool paths) and what a campaign run takes to run with the console. A shape that
varies (a reason instead of figures) is a ``total=False`` TypedDict: its keys present by case."""

from __future__ import annotations

from typing import TYPE_CHECKING, NotRequired, Protocol, TypedDict

if TYPE_CHECKING:
    from rig.campaign.run import StopRequest
    from rig.campaign.runner import SessionFactory

__all__ = [
    "CutCase",
    "LiveState",
    "LobesAt",
    "LoggerStatus",
    "MachineReport",
    "Margin",
    "Peak",
    "PositionEstimate",
    "RunKwargs",
    "RunToolpath",
    "Segment",
    "WriterCounts",
]

#: A tool-path segment: [block, kind, x0, y0, x1, y1, z0, z1] (mm)
Segment = list[int | float]


class CutCase(TypedDict, total=False):
    """The run's cut for the lobes (teeth ... spindle_rpm; ``modes`` as [axis, Hz, damping
    ratio, N/m]), or only ``reason`` when there are none."""

    reason: str
    teeth: int
    milling: str
    radial_immersion: float
    kt_n_m2: float
    kn_n_m2: float
    modes: list[list[str | float]]
    depth_mm: float
    spindle_rpm: float


class LobesAt(TypedDict, total=False):
    """The lobes at one speed: limiting depth (mm; None: stable at every depth searched),
    chatter frequency (Hz) and kind; or ``rpm`` and ``reason`` when not computed."""

    rpm: float
    depth_limit_mm: float | None
    predicted_hz: float | None
    kind: str
    reason: str


class Margin(LobesAt, total=False):
    """The run's depth against the limiting depth at this speed (``depth_pct``: depth / limit,
    %; over 100: the lobes predict chatter), or ``reason``."""

    depth_mm: float
    depth_pct: float | None
    stable: bool


class Peak(TypedDict, total=False):
    """The spectrum's strongest frequency off the spindle harmonics (Hz), its energy share and
    the detector's verdict on the window; ``judged`` False with the reason otherwise."""

    peak_hz: float | None
    judged: bool
    chatter: bool
    energy_ratio: float | None
    energy_threshold: float
    reason: str


class WriterCounts(Protocol):
    """The run writer's counts the logger's health reads (rig.log's ``WriterStats``)."""

    @property
    def samples_written(self) -> int: ...
    @property
    def samples_dropped(self) -> int: ...
    @property
    def samples_missing(self) -> int: ...


class LoggerStatus(TypedDict):
    """The logger's health: sample rate configured and achieved (Hz) and its deviation (%),
    samples received, written and lost (written, lost: once the writer runs), whether it is
    judged yet, and the flag with why."""

    configured_hz: float
    received: int
    tolerance_pct: float
    achieved_hz: float | None
    rate_dev_pct: float | None
    written: NotRequired[int]
    lost: NotRequired[int]
    written_pct: float | None
    judged: bool
    flag: bool
    why: str


class LiveState(TypedDict):
    """Whether a live run feeds the page, its logger is alive, why it ended ("closed", "gone"
    or "") and until when a lingering server stays (wall s since the epoch)."""

    live: bool
    alive: bool
    ended: str
    until: NotRequired[float | None]


class RunKwargs(TypedDict):
    """What :func:`rig.campaign.run_campaign` takes to run with the console."""

    session_factory: SessionFactory
    stop: StopRequest


class PositionEstimate(TypedDict):
    """Where the tool is estimated (mm), at what feed (mm/min) and speed (rpm), and where its
    block ends (mm); None: not known."""

    pos_mm: list[float] | None
    feed_mm_min: float | None
    spindle_rpm: float | None
    block_end_mm: list[float] | None


class RunToolpath(TypedDict):
    """A run file's planned segments, executed points and how they were found."""

    toolpath: list[Segment]
    trail: list[list[float | None]]
    source: str


class MachineReport(TypedDict, total=False):
    """The machine as its controller reports it: state, position (mm), feed, speed, where it
    comes from; GRBL's overrides (%) and whether the position is estimated."""

    state: str
    pos_mm: list[float] | None
    feed_mm_min: float | None
    spindle_rpm: float | None
    source: str
    overrides_pct: dict[str, int] | None
    estimated: bool
