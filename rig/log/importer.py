"""`cutlab data import`: DynoWare / CSV exports into ordinary HDF5 run files.

Each export is read as `cutlab analyze forces` reads it (:func:`analysis.identify.load_exports`:
columns mapped to cutlab's x, y, z, N, the offset from a zero file, header or ``--zeroed``, the
conditions merged from the header, a conditions table, a file-name pattern and KEY=VALUE pairs)
and written with :class:`rig.log.RunWriter`, so every command that reads run files reads it.

The forces are stored in N as the samples of three channels ``Fx``, ``Fy``, ``Fz`` (cutlab's
frame) behind a unit calibration; ``meta/rig`` records ``import``: the source file, the mapping
used, where the offset comes from; a ``note`` event at sample 0 says the same.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, TypedDict

import numpy as np

from analysis.runs import SAMPLE_FORMAT_VOLTS
from analysis.runs import file as rf
from rig.daq import Calibration, DaqInfo
from rig.log.writer import RunWriter, RunWriterError

if TYPE_CHECKING:  # the readers need scipy (~1 s), loaded by an import, not by `cutlab daq record`
    from analysis.identify import Export, ImportOptions

__all__ = ["ImportedRun", "import_exports", "write_export_run"]

_CHANNELS = ("Fx", "Fy", "Fz")
_BLOCK = 8192


class ImportedRun(TypedDict):
    """A run file written from an export (`cutlab data import --json`): its file, the export,
    samples, rate (Hz), the axes mapping and the offset used, and the conditions recorded."""

    file: str
    source: str
    samples: int
    rate_hz: float
    axes: str
    zero: str
    conditions: dict[str, object]  # as the export stated them: free-form keys


def write_export_run(ex: Export, path: str | Path, overwrite: bool = False) -> ImportedRun:
    """Write one imported export as a run file; returns what was written (JSON-able)."""
    run = ex.run
    info = DaqInfo(
        device="import", physical_channels=_CHANNELS, channel_names=_CHANNELS,
        rate_hz=run.rate_hz, sample_format=SAMPLE_FORMAT_VOLTS,
        input_range_v=float(max(1.0, np.abs(run.force_n).max())), block_samples=_BLOCK,
    )  # fmt: skip
    # Newtons stored as the samples through a unit gain: load_run's forces are the export's.
    cal = Calibration(
        channel_names=_CHANNELS, sensitivity_pc_n=1.0, range_n_v=1.0, sign=1.0,
        crosstalk=np.eye(3), amp_sensitivity_pc_n=1.0,
        calibration_id=f"import:{Path(str(ex.run.name))}", dynamometer="imported export",
    )  # fmt: skip
    source = {"source": str(ex.source), "axes": ex.axes, "zero": ex.zero,
              "stored": "forces in N as the samples, unit calibration"}  # fmt: skip
    conditions = {k: v for k, v in asdict(run.conditions).items()
                  if not (isinstance(v, float) and math.isnan(v))}  # fmt: skip
    # what the header or the conditions table stated beside the fitted form: the feed in
    # mm/min, the teeth, a slot's mode (the catalogue's columns)
    for key in ("feed_mm_min", "teeth", "mode"):
        if key in ex.stated:
            conditions[key] = ex.stated[key]
    conditions["source_file"] = str(ex.source)
    w = RunWriter(path, info, cal, clock=lambda: 0.0, overwrite=overwrite)
    try:
        w.on_start(info, 0.0)
        w.set_conditions(conditions)
        w.set_rig({"import": source})
        w.event(rf.EV_NOTE, f"imported from {Path(str(ex.source)).name}: axes {ex.axes}; "
                f"offset: {ex.zero}", sample=0)  # fmt: skip
        for a in range(0, len(run.force_n), _BLOCK):
            w.put_block(a, np.ascontiguousarray(run.force_n[a : a + _BLOCK].T))
    except BaseException as exc:
        w.close(rf.STATUS_FAIL, f"{type(exc).__name__}: {exc}"[:500])
        raise
    w.close(rf.STATUS_SUCCESS, f"imported from {ex.source}")
    return {"file": str(path), "source": str(ex.source), "samples": len(run.force_n),
            "rate_hz": run.rate_hz, "axes": ex.axes, "zero": ex.zero,
            "conditions": conditions}  # fmt: skip


def import_exports(
    paths: Sequence[str | Path],
    out_dir: str | Path,
    overrides: Mapping[str, object] | None = None,
    options: ImportOptions | None = None,
    *,
    rig_path: str | Path | None = None,
    rate_hz: float | None = None,
    tool: str | None = None,
    overwrite: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> list[ImportedRun]:
    """Import every export into ``out_dir/<name>.h5``, one at a time (memory: one export); bad
    input stops at that file (the ones before it are written). An existing output is refused
    unless ``overwrite``, before anything is written."""
    out = Path(out_dir)
    targets = [out / f"{Path(str(p)).stem}.h5" for p in paths]
    if len(set(targets)) != len(targets):
        raise RunWriterError("two exports have the same name: they would write the same run file")
    if not overwrite:
        for t in targets:
            if t.exists():
                raise RunWriterError(f"{t}: file exists (--force replaces it)")
    written: list[ImportedRun] = []
    from analysis.identify import load_exports

    exports = load_exports(paths, overrides, rig_path, rate_hz, tool, options)
    for k, (ex, t) in enumerate(zip(exports, targets)):
        written.append(write_export_run(ex, t, overwrite=overwrite))
        if progress:
            progress(k + 1, len(targets))
    return written
