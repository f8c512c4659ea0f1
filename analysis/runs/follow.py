"""Reading a run file while it is being written (HDF5 SWMR read mode): :class:`RunFollower`
and :func:`follow`. The layout is :mod:`analysis.runs.layout`'s."""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from pathlib import Path

import h5py
import numpy as np
import pandas as pd

from analysis.runs import file as rf


class RunFollower:
    """Read a run while it is being written (HDF5 SWMR read mode).

    Each :meth:`poll` returns the samples and events that arrived since the previous call::

        with RunFollower("run.h5") as fol:
            while not fol.finished:
                first, volts, events = fol.poll()   # first stored index, (k, c) V, DataFrame
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        rf.open_run_file(self.path).close()  # format check with clear errors
        self._f = h5py.File(self.path, "r", libver="latest", swmr=True)
        self._n = 0
        self._n_events = 0
        fa = self._f[rf.FORCES].attrs
        self.rate_hz = float(fa["rate_hz"])
        self.channel_names = rf.names_attr(fa["channel_names"])
        self._coeff = self._f[rf.SCALING_COEFF][()] if rf.SCALING_COEFF in self._f else None
        self.status = rf.STATUS_RUNNING

    def poll(self) -> tuple[int, np.ndarray, pd.DataFrame]:
        """New stored samples as (first stored index, volts (k, c), new events)."""
        # Status first: a writer flushes every sample before it marks the run closed, so a
        # "closed" status read here guarantees the reads below see the final samples.
        st = self._f[rf.meta_path(rf.META_STATUS)]
        st.refresh()
        text = rf.decode_text(st)
        status = json.loads(text).get("status", rf.STATUS_RUNNING) if text else rf.STATUS_RUNNING
        ds = rf.samples_dataset(self._f)
        ds.refresh()
        n = int(ds.shape[0])
        if rf.FLUSHED in self._f:  # files written before it: the extent only
            fl = self._f[rf.FLUSHED]
            fl.refresh()
            n = min(n, int(fl[0])) if status == rf.STATUS_RUNNING else n
        block = ds[self._n : n]
        volts = rf.raw_to_volts(block, self._coeff) if self._coeff is not None else block
        first, self._n = self._n, n
        ev = self._f[rf.EVENTS]
        ev.refresh()
        m = int(ev.shape[0])
        new_events = rf.events_frame(ev[self._n_events : m])
        self._n_events = m
        self.status = status
        return first, np.asarray(volts, dtype=np.float64), new_events

    @property
    def finished(self) -> bool:
        """True once the writer has closed the run (status other than running)."""
        return self.status != rf.STATUS_RUNNING

    def close(self) -> None:
        self._f.close()

    def __enter__(self) -> RunFollower:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def follow(
    path: str | Path, poll_s: float = 0.2, idle_timeout_s: float = 10.0
) -> Iterator[tuple[int, np.ndarray, pd.DataFrame]]:
    """Yield ``(first stored index, volts (k, c), new events)`` as a run grows.

    Ends when the writer closes the run, or after ``idle_timeout_s`` without new samples (a
    killed writer never closes its file).
    """
    with RunFollower(path) as fol:
        idle_since = time.monotonic()
        while True:
            first, volts, ev = fol.poll()
            if len(volts) or len(ev):
                idle_since = time.monotonic()
                yield first, volts, ev
            if fol.finished:
                return
            if time.monotonic() - idle_since > idle_timeout_s:
                return
            time.sleep(poll_s)
