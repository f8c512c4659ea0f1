"""The adaptive loop's JSON-shaped results, keys and value types spelled out: what the live
console shows beside the force and what a run's record and the bench keep; and where it writes
its notes."""

from __future__ import annotations

from typing import Protocol, TypedDict

__all__ = ["AdaptiveStatus", "AdaptiveSummary", "NoteWriter"]


class AdaptiveStatus(TypedDict):
    """The loop now (:meth:`AdaptiveController.live_status`): target and limit (N), the last
    revolution's force (N; None before the first), the overrides commanded and reported (%),
    the state (idle, air, cutting, hold) and why it holds."""

    mode: str
    target_force_n: float
    max_force_n: float
    force_n: float | None
    feed_pct: int
    spindle_pct: int
    reported_pct: list[int] | None
    state: str
    hold: str | None


class AdaptiveSummary(TypedDict):
    """A run under the loop (:meth:`AdaptiveController.summary`): revolutions, decisions and
    override bytes; the loop's latency (ms; None without a decision) and CPU (s); the chatter
    times (run-clock s); the revolutions and s at an override limit."""

    mode: str
    target_force_n: float
    revolutions: int
    cutting_revolutions: int
    decisions: int
    override_bytes: int
    hold: str | None
    latency_p50_ms: float | None
    latency_p95_ms: float | None
    cpu_s: float
    chatter_at_s: float | None
    chatter_cleared_s: float | None
    saturated_revolutions: int
    saturated_s: float


class NoteWriter(Protocol):
    """Where the loop writes its notes: the run's writer (rig.log's ``RunWriter``) or the
    terminal's printer of `cutlab dnc send --adaptive`."""

    def event(self, kind: str, message: str = "", *, time_s: float | None = None) -> None: ...
