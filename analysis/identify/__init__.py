"""Force coefficients from recorded runs: reduce each run to its revolution average, fit the
face-mill or end-mill model, validate by prediction; runs from HDF5 files or DynoWare / CSV
exports (:func:`fit_files` does all of it from files; :func:`load_export` reads one export with
its axis mapping, offset and conditions table row).
"""

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # the names as the type checker sees them; at run time each loads on first use
    from analysis.identify._common import CI_NOTE, synthetic_run
    from analysis.identify.axes import AxisMap, check_axes, parse_axes
    from analysis.identify.conditions import ConditionsTable, load_conditions_table
    from analysis.identify.endmill import fit_endmill
    from analysis.identify.facemill import (
        ForceRun,
        RunConditions,
        fit_facemill,
        fit_facemill_runs,
        reduce_run,
        reduce_run_file,
    )
    from analysis.identify.files import fit_files
    from analysis.identify.importers import (
        Export,
        import_run,
        load_export,
        merge_conditions,
        read_force_table,
    )
    from analysis.identify.options import ImportOptions
    from analysis.identify.reading import (
        find_tool,
        load_exports,
        reduce_files,
        tool_teeth,
    )
    from analysis.identify.results import ForcesResult
    from analysis.identify.validate import (
        compare_runs,
        plot_comparison,
        plot_waveforms,
        predicted_mean,
    )

# Loaded on first use (PEP 562): the fits need scipy (signal, stats, optimize: ~1.5 s), which
# `cutlab daq record` and every command that only parses a conditions argument should not pay.
_LAZY = {
    "analysis.identify._common": ("CI_NOTE", "synthetic_run"),
    "analysis.identify.axes": (
        "AxisMap",
        "check_axes",
        "parse_axes",
    ),
    "analysis.identify.conditions": (
        "ConditionsTable",
        "load_conditions_table",
    ),
    "analysis.identify.endmill": ("fit_endmill",),
    "analysis.identify.facemill": (
        "ForceRun",
        "RunConditions",
        "fit_facemill",
        "fit_facemill_runs",
        "reduce_run",
        "reduce_run_file",
    ),
    "analysis.identify.files": ("fit_files",),
    "analysis.identify.options": ("ImportOptions",),
    "analysis.identify.reading": (
        "find_tool",
        "load_exports",
        "reduce_files",
        "tool_teeth",
    ),
    "analysis.identify.importers": (
        "Export",
        "import_run",
        "load_export",
        "merge_conditions",
        "read_force_table",
    ),
    "analysis.identify.results": ("ForcesResult",),
    "analysis.identify.validate": (
        "compare_runs",
        "plot_comparison",
        "plot_waveforms",
        "predicted_mean",
    ),
}
_WHERE = {name: module for module, names in _LAZY.items() for name in names}


def __getattr__(name: str) -> Any:
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(_WHERE[name]), name)
    globals()[name] = value
    return value


__all__ = [
    "AxisMap",
    "CI_NOTE",
    "ConditionsTable",
    "Export",
    "ForceRun",
    "ForcesResult",
    "ImportOptions",
    "RunConditions",
    "check_axes",
    "compare_runs",
    "find_tool",
    "fit_endmill",
    "fit_facemill",
    "fit_facemill_runs",
    "fit_files",
    "import_run",
    "load_conditions_table",
    "load_export",
    "load_exports",
    "merge_conditions",
    "parse_axes",
    "plot_comparison",
    "plot_waveforms",
    "predicted_mean",
    "read_force_table",
    "reduce_files",
    "reduce_run",
    "reduce_run_file",
    "synthetic_run",
    "tool_teeth",
]
