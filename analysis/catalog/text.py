"""What ``cutlab catalog`` prints: the index update in one line, a run's row as text, the query's
table rows; and which catalogue a folder and an index file name."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import pandas as pd

from analysis.catalog.query import MAIN_COLUMNS

__all__ = ["catalog_named", "fit_line", "index_line", "query_rows", "show_lines"]


def catalog_named(folder: str | None, index: str | None) -> str | None:
    """The catalogue named by an archive folder or an index file (both: they must agree), else
    None (the current folder's or a parent's)."""
    from analysis.errors import AnalysisError

    if folder is not None and index is not None:
        if Path(folder).resolve() != Path(index).resolve():
            raise AnalysisError(f"catalog: DIR {folder!r} and --index {index!r} name two "
                                "catalogues; give one")  # fmt: skip
    return folder if folder is not None else index


def index_line(out: Mapping[str, object]) -> str:
    """:func:`~analysis.catalog.update_index`'s counts, statuses and time in one line."""
    statuses = out["statuses"]
    assert isinstance(statuses, Mapping)
    seconds = out["seconds"]
    assert isinstance(seconds, float)
    return (f"{out['files']} run file(s): {out['added']} added, {out['updated']} updated, "
            f"{out['unchanged']} unchanged, {out['removed']} removed; {out['runs_in_index']} in "
            f"the index ({', '.join(f'{k} {v}' for k, v in sorted(statuses.items()))}); "
            f"{seconds:.2f} s")  # fmt: skip


def fit_line(out: Mapping[str, object]) -> str:
    """A catalogue fit (:func:`~analysis.catalog.fit_catalog`): its runs, and what came from the
    cache."""
    c = out["catalog"]
    assert isinstance(c, Mapping)
    how = ("the fit from the cache" if c["fit_cached"] else
           f"{c['cached']} from the cache, {c['reduced']} reduced")  # fmt: skip
    return f"{c['runs']} run(s) from {c['index']}: {how}"


def query_rows(df: pd.DataFrame, all_columns: bool = False) -> list[dict[str, object]]:
    """The table rows of a query: the main columns and the path (it tells two copies of an
    archive, same campaign and run names, apart), or every column."""
    cols = list(df.columns) if all_columns else [*MAIN_COLUMNS, "path"]
    return [{str(k): v for k, v in r.items()} for r in df[cols].to_dict("records")]


def show_lines(row: dict[str, object]) -> list[str]:
    """A run's catalogue row, one ``key value`` line per column, then its conditions."""
    conditions = row.pop("conditions") or {}
    assert isinstance(conditions, Mapping)
    items = [*row.items(), *((f"conditions.{k}", v) for k, v in conditions.items())]
    return [f"{k:<28} {v}" for k, v in items]
