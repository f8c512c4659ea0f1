"""Closed-loop machining (issue 29): GRBL real-time overrides from the live force.

:class:`AdaptiveController` (a DAQ sink: per-revolution force in, override bytes out, safety
holds first), :class:`AdaptiveSettings`, and :class:`AdaptiveSession` (the controller in a
campaign run's rig session). See :mod:`rig.adaptive.controller`; the settings in
:mod:`rig.adaptive.settings`, the record in :mod:`rig.adaptive.record`.
"""

from rig.adaptive.controller import AdaptiveController
from rig.adaptive.pockets import nearest_pocket_rpm
from rig.adaptive.session import AdaptiveSession
from rig.adaptive.settings import MODES, AdaptiveSettings

__all__ = [
    "MODES",
    "AdaptiveController",
    "AdaptiveSession",
    "AdaptiveSettings",
    "nearest_pocket_rpm",
]
