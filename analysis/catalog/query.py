"""Queries over the run index: pandas' query language, restricted to comparisons.

``DataFrame.query`` evaluates Python: ``@name`` reaches the caller's variables, attribute access
and calls reach anything (``run.__class__...``). An expression is therefore parsed first and
refused unless it is only comparisons (``== != < <= > >= in not in``) of known columns with
numbers, strings, True/False or lists of them, joined by ``and or not & | ~``.
"""

from __future__ import annotations

import ast
import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any, cast

import pandas as pd

from analysis.catalog.index import COLUMNS, RowBase, SqlValue, index_file, load_index
from analysis.errors import AnalysisError
from analysis.validation import JsonObject

#: Columns shown by default (the query's result has them all).
MAIN_COLUMNS = ("campaign", "run", "group", "status", "tool", "material", "spindle_rpm",
                "feed_mm_min", "fz_mm", "depth_mm", "width_mm")  # fmt: skip
#: The syntax an expression may use besides names and constants (checked further below).
_ALLOWED = (ast.Expression, ast.BoolOp, ast.And, ast.Or, ast.Not, ast.Invert, ast.BitAnd,
            ast.BitOr, ast.Load, ast.List, ast.Tuple, ast.USub, ast.UAdd, ast.Compare, ast.Eq,
            ast.NotEq, ast.Lt, ast.LtE, ast.Gt, ast.GtE, ast.In, ast.NotIn)  # fmt: skip
_HELP = ("use comparisons (== != < <= > >= in, not in) of columns with numbers, strings or "
         "lists, joined by and / or / not, e.g. \"material == 'GM241' and 0.2 <= fz_mm <= 0.4\"")


#: The most comparisons a query may join, and the deepest it may nest (and/or/not/&/|/~ and
#: parentheses as a syntax tree): pandas evaluates a query recursively (about 350 terms end in
#: RecursionError), Python's parser too; a query a lab writes has a handful.
MAX_QUERY_TERMS = 100
MAX_QUERY_DEPTH = 128


def _shown(expr: str) -> str:
    """The query in a message, cut to one readable line."""
    text = " ".join(expr.split())
    return repr(text if len(text) <= 80 else text[:60] + " ... " + text[-15:])


def check_query(expr: str, columns: Iterable[str]) -> None:
    """Raise unless ``expr`` is a plain comparison expression over ``columns`` (one line)."""
    where = f"query {_shown(expr)}"
    try:
        tree = ast.parse(expr.strip(), mode="eval")
    except SyntaxError as exc:
        raise AnalysisError(f"{where}: not an expression (column {exc.offset}: {exc.msg}); "
                            f"{_HELP}") from None  # fmt: skip
    except (RecursionError, MemoryError):  # the parser's own limit (e.g. 5000 x "not")
        raise AnalysisError(f"{where}: nested too deeply to parse; at most {MAX_QUERY_DEPTH} "
                            "levels") from None  # fmt: skip
    terms, depth = 0, 0
    todo: list[tuple[ast.AST, int]] = [(tree, 1)]
    while todo:  # (not ast.walk: the depth too)
        node, d = todo.pop()
        depth = max(depth, d)
        terms += isinstance(node, ast.Compare)
        todo.extend((child, d + 1) for child in ast.iter_child_nodes(node))
    if terms > MAX_QUERY_TERMS:
        raise AnalysisError(f"{where} has {terms} terms (comparisons); at most "
                            f"{MAX_QUERY_TERMS} (a list is one: run in ['a', 'b'])")  # fmt: skip
    if depth > MAX_QUERY_DEPTH:
        raise AnalysisError(f"{where} nests {depth} levels deep; at most {MAX_QUERY_DEPTH}")
    known = set(columns)
    for node in ast.walk(tree):
        ok = isinstance(node, _ALLOWED)
        if isinstance(node, ast.Constant):
            ok = isinstance(node.value, str | int | float | bool)
        elif isinstance(node, ast.Name):
            if node.id not in known and node.id not in ("True", "False"):
                raise AnalysisError(f"{where}: unknown column {node.id!r}; known: "
                                    f"{', '.join(sorted(known))}")  # fmt: skip
            ok = True
        elif isinstance(node, ast.UnaryOp):
            ok = isinstance(node.op, ast.Not | ast.Invert | ast.USub | ast.UAdd)
        elif isinstance(node, ast.BinOp):  # & and | between comparisons, as pandas writes them
            ok = isinstance(node.op, ast.BitAnd | ast.BitOr)
        if not ok:
            text = ast.get_source_segment(expr.strip(), node) or type(node).__name__
            raise AnalysisError(f"{where}: {text!r} is not allowed; {_HELP}")


_SQL_OPS = {ast.Eq: "=", ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">="}
_FLIPPED = {ast.Eq: ast.Eq, ast.Lt: ast.Gt, ast.LtE: ast.GtE, ast.Gt: ast.Lt, ast.GtE: ast.LtE}


def _value(node: ast.AST, column: str) -> tuple[bool, Any]:
    """(True, value) when ``node`` is a constant of the column's SQL type, else (False, None)."""
    sign = 1
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.UAdd):
        sign, node = (-1 if isinstance(node.op, ast.USub) else 1), node.operand
    if not isinstance(node, ast.Constant) or isinstance(node.value, bool):
        return False, None
    v = node.value
    if COLUMNS[column].startswith("TEXT"):
        return (isinstance(v, str) and sign == 1), v
    return isinstance(v, int | float), (sign * v if isinstance(v, int | float) else None)


def sql_prefilter(expr: str) -> tuple[str, list[SqlValue]]:
    """An SQL condition that every row ``expr`` selects meets (checked expressions only): the
    comparisons of an index column with a constant of its type joined by ``and`` at the top.
    SQLite then reads a query's rows, not the whole index; pandas still decides each row, so
    what pandas does with NaN, ``or``, ``not`` and mixed types is unchanged."""
    parts: list[str] = []
    params: list[SqlValue] = []

    def compare(a: ast.AST, op: ast.cmpop, b: ast.AST) -> None:
        if not isinstance(a, ast.Name) and type(op) in _FLIPPED:
            a, b, op = b, a, _FLIPPED[type(op)]()
        if not isinstance(a, ast.Name) or a.id not in COLUMNS:
            return
        if type(op) in _SQL_OPS:
            ok, v = _value(b, a.id)
            if ok:
                parts.append(f'"{a.id}" {_SQL_OPS[type(op)]} ?')
                params.append(v)
        elif isinstance(op, ast.In) and isinstance(b, ast.List | ast.Tuple):
            values = [_value(e, a.id) for e in b.elts]
            if all(ok for ok, _ in values):
                parts.append(f'"{a.id}" IN ({", ".join("?" * len(values))})')
                params.extend(v for _, v in values)

    def walk(node: ast.AST) -> None:
        if isinstance(node, ast.BoolOp) and isinstance(node.op, ast.And):
            for v in node.values:
                walk(v)
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.BitAnd):
            walk(node.left)
            walk(node.right)
        elif isinstance(node, ast.Compare):
            operands = [node.left, *node.comparators]
            for a, op, b in zip(operands, node.ops, operands[1:]):
                compare(a, op, b)

    walk(ast.parse(expr.strip(), mode="eval").body)
    return " AND ".join(parts), params


def query_runs(expr: str | None, index: str | Path | None = None) -> pd.DataFrame:
    """The index's runs matching ``expr`` (all without one), one row per run file."""
    if not expr or not expr.strip():
        return load_index(index)
    ipath = index_file(index)
    check_query(expr, [*COLUMNS, "file"])
    df = load_index(ipath, *sql_prefilter(expr))
    try:
        out = df.query(expr, engine="python", local_dict={}, global_dict={})
    except Exception as exc:  # noqa: BLE001 - a checked expression can still compare badly
        raise AnalysisError(f"query {expr!r}: {type(exc).__name__}: {exc}") from None
    if not isinstance(out, pd.DataFrame):
        raise AnalysisError(f"query {expr!r}: not a condition on the rows; {_HELP}")
    return out.reset_index(drop=True)


def records(df: pd.DataFrame) -> list[dict[str, object]]:
    """JSON-able rows (``conditions`` and ``events`` as objects, NaN as None)."""
    out: list[dict[str, object]] = []
    for record in df.astype(object).where(df.notna(), None).to_dict("records"):
        row = {str(k): v for k, v in record.items()}
        for key in ("conditions", "events"):
            if isinstance(row.get(key), str):
                row[key] = json.loads(row[key])
        out.append(row)
    return out


class RunRow(RowBase):
    """An index row as shown (`cutlab catalog show`): ``events`` and ``conditions`` as objects."""

    events: dict[str, int] | None
    conditions: JsonObject | None


def show_run(name: str, index: str | Path | None = None) -> RunRow:
    """The index row of one run: ``name`` is a run (file stem), ``CAMPAIGN/RUN`` or a path."""
    df = load_index(index)
    campaign, _, run = name.rpartition("/")
    hit = df[(df["run"] == run) & ((df["campaign"] == campaign) | (campaign == ""))]
    if hit.empty:
        hit = df[(df["path"] == name) | (df["file"] == str(Path(name).resolve()))]
    if len(hit) != 1:
        what = ", ".join(f"{c}/{r} ({p})" for c, r, p in hit[["campaign", "run", "path"]].values)
        raise AnalysisError(
            f"run {name!r}: " + (f"{len(hit)} runs match ({what}); give CAMPAIGN/RUN or the path"
                                 if len(hit) else "not in the catalogue")  # fmt: skip
        )
    return cast(RunRow, records(hit)[0])  # a row of the index's frame: COLUMNS
