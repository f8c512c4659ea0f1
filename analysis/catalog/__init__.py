"""The run catalogue: an index of every run file's metadata (campaign, conditions, status,
sample counts, events, hash) in one SQLite file, queried with pandas' query language restricted
to comparisons, and force identification over a query with the per-run reductions as dask tasks
(local threads or a dask.distributed cluster), cached by file hash.
"""

from analysis.catalog.compute import CONNECT_TIMEOUT_S, CachedMapper, compute, fit_catalog
from analysis.catalog.index import (
    INDEX_NAME,
    IndexRow,
    IndexUpdate,
    index_file,
    load_index,
    update_index,
)
from analysis.catalog.query import (
    MAIN_COLUMNS,
    RunRow,
    check_query,
    query_runs,
    records,
    show_run,
)
from analysis.catalog.text import catalog_named, fit_line, index_line, query_rows, show_lines

__all__ = [
    "CONNECT_TIMEOUT_S",
    "INDEX_NAME",
    "MAIN_COLUMNS",
    "CachedMapper",
    "IndexRow",
    "IndexUpdate",
    "RunRow",
    "catalog_named",
    "check_query",
    "compute",
    "fit_catalog",
    "fit_line",
    "index_file",
    "index_line",
    "load_index",
    "query_rows",
    "query_runs",
    "records",
    "show_lines",
    "show_run",
    "update_index",
]
