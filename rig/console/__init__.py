"""The live lab console: a local web page beside a campaign (force traces as they are cut, the
block executing, the machine, the stream, progress, events; feed hold / resume / abort) and a
browser of finished runs.

Quick tour::

    from rig.console import live_console
    with live_console(campaign, out_root, port=8765) as live:   # page at http://127.0.0.1:8765/
        result = run_campaign(campaign, out_root=out_root, **live.run_kwargs())

Modules: :mod:`~rig.console.ring` (the shared-memory ring between the campaign and the server),
:mod:`~rig.console.live` (the campaign side: the tap, the state, the commands),
:mod:`~rig.console.server` (Starlette app; needs the ``console`` extra), ``static/`` (the page,
uPlot vendored with its licence).
"""

from rig.console.live import LiveCampaign, LiveSink, live_console, machine_report
from rig.console.ring import RingError, RingReader, RingWriter

__all__ = [
    "LiveCampaign",
    "LiveSink",
    "RingError",
    "RingReader",
    "RingWriter",
    "live_console",
    "machine_report",
]
