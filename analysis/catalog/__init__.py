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

__all__ = [
    "CONNECT_TIMEOUT_S",
    "INDEX_NAME",
    "MAIN_COLUMNS",
    "CachedMapper",
    "IndexRow",
    "IndexUpdate",
    "RunRow",
    "check_query",
    "compute",
    "fit_catalog",
    "index_file",
    "load_index",
    "query_runs",
    "records",
    "show_run",
    "update_index",
]
