"""The live lab console: a local web page beside a campaign (force traces as they are cut, the
block executing, the machine, the stream, progress, events; feed hold / resume / abort) and a
browser of finished runs.

Quick tour::

    from rig.console import live_console
    with live_console(campaign, out_root, port=8765) as live:   # page at http://127.0.0.1:8765/
        result = run_campaign(campaign, out_root=out_root, **live.run_kwargs())

Modules: :mod:`~rig.console.ring` (the shared-memory ring between the campaign and the server);
the campaign side: :mod:`~rig.console.live` (the state, the commands, :func:`live_console`),
:mod:`~rig.console.session` (the tap), :mod:`~rig.console.program_path` (the DRO's estimate,
the toolpath), :mod:`~rig.console.health` (the logger's health), :mod:`~rig.console.process`
(the server's process); the server side (needs the ``console`` extra):
:mod:`~rig.console.server` (the Starlette app), :mod:`~rig.console.guard` (Host, Origin,
token), :mod:`~rig.console.hub` (the target, history), :mod:`~rig.console.frames` (frames and
traces), :mod:`~rig.console.trail` (the executed path), :mod:`~rig.console.run_path` (a
browsed run's toolpath from its file), :mod:`~rig.console.chatter` (the lobes
at the current speed, the detected peak); :mod:`~rig.console.common` (what both share);
``static/`` (the page: console.js, panels.js, view3d.js; uPlot vendored with its licence).
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
