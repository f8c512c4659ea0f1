"""What the ``cutlab rules`` commands do (seed 001): a rule derived from feed-sweep run files,
and the rule base's groups as plain data (store a rule file, show, look up, list, export).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import cast

from analysis.errors import AnalysisError
from analysis.output import table_lines
from analysis.rules.basefeed import (
    BaseFeedResult,
    BaseFeedSettings,
    Criterion,
    find_base_feed,
    sweep_runs_from_files,
)
from analysis.rules.rule import N_BINS, FeedRule, derive_rule, load_rule
from analysis.rules.rulebase import GroupExistsError, GroupKey, RuleBase, default_path
from analysis.validation import JsonObject, JsonValue

MIN_SWEEP_RUNS = 4  # fewer runs than this: no base-feed detection


@dataclass(frozen=True)
class DerivedRule:
    """A rule derived from a feed sweep, with how its base feed and limits were chosen."""

    rule: FeedRule
    base_feed_mm_min: float
    base_feed_reason: str  # a whole sentence ("base feed 1000 mm/min: ...")
    min_feed_mm_min: float
    max_feed_mm_min: float
    reference_load_pct: float
    detection: BaseFeedResult | None  # None with fewer than MIN_SWEEP_RUNS runs

    def summary(self, rule_path: str | Path) -> JsonObject:
        """Plain data for JSON: the rule file (as written to ``rule_path``), the choices made,
        the sweep's runs and intervals (empty without detection) and the bins."""
        det = self.detection
        return {
            "rule": str(rule_path),
            "name": self.rule.name,
            "base_feed_mm_min": self.base_feed_mm_min,
            "base_feed_reason": self.base_feed_reason,
            "min_feed_mm_min": self.min_feed_mm_min,
            "max_feed_mm_min": self.max_feed_mm_min,
            "reference_load_pct": self.reference_load_pct,
            "runs": _rows([vars(r) for r in det.runs]) if det else [],
            "intervals": _rows(det.table()) if det else [],
            "bins": _rows(self.rule.table()),
        }

    def summary_line(self, rule_path: str | Path) -> str:
        """What was written, one line."""
        return (f"wrote {rule_path} ({self.rule.n_bins} bins, base {self.base_feed_mm_min:g} "
                f"mm/min at {self.reference_load_pct:.4g} %)")  # fmt: skip

    def lines(self) -> list[str]:
        """The text `cutlab rules derive` prints: the base feed's reason, the sweep's runs and
        intervals (with a detection), the bins."""
        det, text = self.detection, [self.base_feed_reason]
        if det:
            text += [*table_lines([vars(r) for r in det.runs]), "", *table_lines(det.table())]
        return [*text, "", *table_lines(self.rule.table())]


def _rows(rows: Sequence[Mapping[str, JsonValue]]) -> list[JsonValue]:
    """Rows of scalars as JSON values (a copy: lists of dicts are invariant in their type)."""
    return [dict(r) for r in rows]


def derive_from_sweep(
    paths: Sequence[str | Path],
    name: str,
    *,
    base_feed_mm_min: float | None = None,
    min_feed_mm_min: float | None = None,
    max_feed_mm_min: float | None = None,
    machine: str | Path | None = None,
    reference_load_pct: float | None = None,
    exponent: float = 1.0,
    n_bins: int = N_BINS,
    slope_ratio: float = BaseFeedSettings.slope_ratio,
    vibration_ratio: float = BaseFeedSettings.vibration_ratio,
    criterion: Criterion = BaseFeedSettings.criterion,
) -> DerivedRule:
    """Seed 001 steps 2-3 from feed-sweep run files: the base feed (detected with
    :class:`BaseFeedSettings` of the ratios and criterion, unless given), the feed limits
    (default 0.1 and 3.5 x base, clamped to ``machine``'s feed limits when given), the reference
    load (default: a slot at the runs' depth with their tool) and the rule."""
    from analysis.config import load_machine

    sweep = sweep_runs_from_files(paths)
    st = BaseFeedSettings(slope_ratio, vibration_ratio, criterion=criterion)
    found = find_base_feed(sweep.runs, st) if len(sweep.runs) >= MIN_SWEEP_RUNS else None
    if base_feed_mm_min is not None:
        base = base_feed_mm_min
        how = f"base feed {base_feed_mm_min:g} mm/min given with --base-feed"
    elif found is not None and found.found and found.base_feed_mm_min is not None:
        base, how = found.base_feed_mm_min, found.message
    else:
        why = found.message if found is not None else f"only {len(sweep.runs)} runs"
        raise AnalysisError(f"no base feed found: {why}. Give one with --base-feed.")
    lo = min_feed_mm_min if min_feed_mm_min is not None else 0.1 * base
    hi = max_feed_mm_min if max_feed_mm_min is not None else 3.5 * base
    if machine:
        m = load_machine(machine)
        lo, hi = max(lo, m.feed_min_mm_min), min(hi, m.feed_max_mm_min)
    ref = reference_load_pct if reference_load_pct is not None else sweep.reference_load_pct
    if ref is None or not math.isfinite(ref):
        raise AnalysisError(
            "the runs do not say tool and depth_mm in their conditions: give --reference-load (%)"
        )
    src = ", ".join(Path(p).name for p in paths)
    rule = derive_rule(
        name, lo, base, hi, ref, exponent=exponent, n_bins=n_bins, description=how,
        source=f"feed sweep: {src}", tool=sweep.tool or "",
    )  # fmt: skip
    return DerivedRule(rule, base, how, lo, hi, ref, found)


def _as_key(key: GroupKey | Mapping[str, str | float]) -> GroupKey:
    if isinstance(key, GroupKey):
        return key
    return GroupKey(**key)  # type: ignore[arg-type]  # __post_init__ checks each field's value


def add_rule_file(
    rule_path: str | Path,
    key: GroupKey | Mapping[str, str | float],
    db: str | Path | None = None,
    *,
    note: str = "",
    replace: bool = False,
    on_create: Callable[[Path], None] | None = None,
) -> tuple[JsonObject, Path]:
    """Store a rule file for group ``key`` (a :class:`GroupKey` or its fields) in the rule base
    ``db`` (default :func:`default_path`, created if missing: ``on_create(path)`` is told
    first). Returns the stored group's summary and the base's path."""
    path = Path(db) if db is not None else default_path()
    if not path.exists() and on_create is not None:
        on_create(path)
    with RuleBase(path) as rb:
        try:
            gid = rb.import_file(rule_path, _as_key(key), note=note, replace=replace)
        except GroupExistsError as exc:
            raise AnalysisError(
                f"{exc.path}: group {exc.group_id} has this key already; add --replace to "
                "replace its rule"
            ) from None
        return rb.get(gid).summary(), rb.path


def _open(db: str | Path | None) -> RuleBase:
    """An existing rule base (default :func:`default_path`): a path that does not exist is an
    error, not a new empty base (a typo must not read as one)."""
    return RuleBase(db, create=False)


def list_groups(db: str | Path | None = None) -> list[JsonObject]:
    """Every group of the rule base ``db``, as summaries."""
    with _open(db) as rb:
        return [g.summary() for g in rb.list()]


def rule_info(spec: str, db: str | Path | None = None) -> tuple[FeedRule, JsonObject]:
    """A rule by file (an existing ``.toml``), rule name or group id in the base ``db``, and
    its settings and bins as plain data (``from`` says where it was found)."""
    p = Path(spec)
    if p.suffix == ".toml" and p.exists():
        rule, where = load_rule(p), str(p)
    else:
        with _open(db) as rb:
            g = rb.find(spec)
            rule, where = g.rule, f"group {g.id} of {rb.path}"
    info: JsonObject = {
        "name": rule.name,
        "from": where,
        "min_feed_mm_min": rule.min_feed_mm_min,
        "base_feed_mm_min": rule.base_feed_mm_min,
        "max_feed_mm_min": rule.max_feed_mm_min,
        "reference_load_pct": rule.reference_load_pct,
        "exponent": rule.exponent,
        "description": rule.description,
        "source": rule.source,
        "bins": _rows(rule.table()),
    }
    return rule, info


def rule_info_lines(info: Mapping[str, JsonValue]) -> list[str]:
    """``cutlab rules show``: :func:`rule_info`'s settings as ``key: value`` lines, then the
    bins as a table."""
    bins = cast("list[Mapping[str, object]]", info["bins"])
    return [*(f"{k}: {v}" for k, v in info.items() if k != "bins"), *table_lines(bins)]


def lookup_group(
    key: GroupKey | Mapping[str, str | float],
    db: str | Path | None = None,
    exact_only: bool = False,
) -> JsonObject:
    """The rule base's group for ``key`` (a :class:`GroupKey` or its fields): exact, else the
    nearest, stated; as plain data."""
    with _open(db) as rb:
        m = rb.lookup(_as_key(key), exact_only=exact_only)
    return {
        "exact": m.exact,
        "distance": m.distance,
        "statement": m.statement(),
        "differences": {k: list(v) for k, v in m.differences.items()},
        "group": m.group.summary(),
    }


def export_rule(spec: str, path: str | Path, db: str | Path | None = None) -> Path:
    """Write a stored rule (by rule name or group id) to ``path`` exactly as stored."""
    with _open(db) as rb:
        return rb.export(rb.find(spec).id, path)
