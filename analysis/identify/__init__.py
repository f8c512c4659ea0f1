"""Force coefficients from recorded runs: reduce each run to its revolution average, fit the
face-mill or end-mill model, validate by prediction; runs from HDF5 files or DynoWare / CSV
exports (:func:`fit_files` does all of it from files).
"""

from analysis.identify._common import CI_NOTE
from analysis.identify.endmill import fit_endmill
from analysis.identify.facemill import (
    ForceRun,
    RunConditions,
    fit_facemill,
    fit_facemill_runs,
    reduce_run,
    reduce_run_file,
)
from analysis.identify.files import fit_files, reduce_files, tool_teeth
from analysis.identify.importers import import_run, merge_conditions, read_force_table
from analysis.identify.validate import compare_runs, plot_comparison, plot_waveforms, predicted_mean

__all__ = [
    "CI_NOTE",
    "ForceRun",
    "RunConditions",
    "compare_runs",
    "fit_endmill",
    "fit_facemill",
    "fit_facemill_runs",
    "fit_files",
    "import_run",
    "merge_conditions",
    "plot_comparison",
    "plot_waveforms",
    "predicted_mean",
    "read_force_table",
    "reduce_files",
    "reduce_run",
    "reduce_run_file",
    "tool_teeth",
]
