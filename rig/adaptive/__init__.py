"""Closed-loop machining (issue 29): GRBL real-time overrides from the live force.

:class:`AdaptiveController` (a DAQ sink: per-revolution force in, override bytes out, safety
holds first), :class:`AdaptiveSettings`, and :class:`AdaptiveSession` (the controller in a
campaign run's rig session). See :mod:`rig.adaptive.controller`.
"""

from rig.adaptive.controller import (
    MODES,
    AdaptiveController,
    AdaptiveSettings,
    nearest_pocket_rpm,
)
from rig.adaptive.session import AdaptiveSession

__all__ = [
    "MODES",
    "AdaptiveController",
    "AdaptiveSession",
    "AdaptiveSettings",
    "nearest_pocket_rpm",
]
