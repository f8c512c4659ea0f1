"""The rule base: machining groups and their feed rules in SQLite (seed 001 4.2 step 1, Table 1).

A machining group is keyed as seed 001 keys it: part family (die / panel / process / part, e.g.
``trunk/outer/draw/lower-die``), operation (roughing, pencil, rest-roughing, ...), tool diameter and
flute length, material, spindle speed, depth of cut and tolerance. Each group holds its base feed
and its rule (the rule file's TOML text, so an exported rule is byte-for-byte what was imported).

SQLite is the embedded default (path from ``configs/lab.toml``, ``$CUTLAB_RULEBASE`` or ``--db``).
It runs in WAL mode, so readers never block on a writer, and every change is one transaction, so a
writer killed mid-change leaves the base as it was before that change.

Lookup is by exact key, or by nearest match among the groups of the same operation and material:
the distance is the weighted sum of relative differences (tool diameter x4, flute length, spindle,
depth x1, tolerance x0.5) plus 0.25 when the part family differs; the match states every field that
differs, so a user sees exactly what was substituted.
"""

from __future__ import annotations

import datetime as _dt
import os
import sqlite3
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

from analysis.config import REPO_ROOT, config_dir
from analysis.errors import AnalysisError, ConfigError
from analysis.rules.rule import FeedRule, rule_from_toml, rule_to_toml
from analysis.validation import JsonObject, read_toml

SCHEMA_VERSION = 1

_SCHEMA = """
CREATE TABLE IF NOT EXISTS groups (
    id               INTEGER PRIMARY KEY,
    part_family      TEXT NOT NULL,
    operation        TEXT NOT NULL,
    tool_diameter_mm REAL NOT NULL CHECK (tool_diameter_mm > 0),
    flute_length_mm  REAL NOT NULL CHECK (flute_length_mm > 0),
    material         TEXT NOT NULL,
    spindle_rpm      REAL NOT NULL CHECK (spindle_rpm > 0),
    depth_mm         REAL NOT NULL CHECK (depth_mm > 0),
    tolerance_mm     REAL NOT NULL CHECK (tolerance_mm > 0),
    base_feed_mm_min REAL NOT NULL CHECK (base_feed_mm_min > 0),
    rule_name        TEXT NOT NULL,
    rule_toml        TEXT NOT NULL,
    note             TEXT NOT NULL DEFAULT '',
    created_utc      TEXT NOT NULL,
    UNIQUE (part_family, operation, tool_diameter_mm, flute_length_mm, material,
            spindle_rpm, depth_mm, tolerance_mm)
);
"""

# Weights of the nearest-match distance (relative differences), see the module docstring.
_WEIGHTS = {
    "tool_diameter_mm": 4.0,
    "flute_length_mm": 1.0,
    "spindle_rpm": 1.0,
    "depth_mm": 1.0,
    "tolerance_mm": 0.5,
}
_FAMILY_WEIGHT = 0.25


class GroupExistsError(AnalysisError):
    """A group with this key is stored already (``replace=True`` replaces it)."""

    def __init__(self, path: Path, key: GroupKey, group_id: int) -> None:
        self.path, self.key, self.group_id = path, key, group_id
        super().__init__(
            f"{path}: group {group_id} has this key already ({_key_text(key)}); "
            "replace=True replaces its rule"
        )


def _fmt(v: object) -> str:
    """A key value as a user typed it: 30 not 30.0, strings quoted."""
    return f"{v:g}" if isinstance(v, float) else repr(v) if isinstance(v, str) else str(v)


def _key_text(key: GroupKey) -> str:
    return ", ".join(f"{k} = {_fmt(v)}" for k, v in asdict(key).items())


@dataclass(frozen=True)
class GroupKey:
    """What identifies a machining group (seed 001 Table 1)."""

    # the metadata: `cutlab rules add|lookup`'s options (rig.cli.options.model_rows)
    part_family: str = field(metadata={"help": "e.g. trunk/outer/draw/lower-die"})
    operation: str = field(metadata={"help": "roughing, pencil, rest-roughing, ..."})
    tool_diameter_mm: float = field(metadata={"unit": "mm", "gt": 0, "le": 1000})
    flute_length_mm: float = field(metadata={"unit": "mm", "gt": 0, "le": 1000})
    material: str
    spindle_rpm: float = field(metadata={"unit": "rpm", "gt": 0, "le": 100_000})
    depth_mm: float = field(metadata={"unit": "mm", "gt": 0, "le": 1000})
    tolerance_mm: float = field(metadata={"unit": "mm", "gt": 0, "le": 100})

    @classmethod
    def of(cls, values: Mapping[str, object]) -> GroupKey:
        """The key of the fields in ``values`` (e.g. `cutlab rules add`'s options); each
        field's value is checked by :meth:`__post_init__`."""
        return cls(**{f.name: values[f.name] for f in fields(cls)})  # type: ignore[arg-type]

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if f.type == "str" and not str(v).strip():
                raise AnalysisError(f"group key {f.name} = {v!r}: must not be empty")
            if f.type == "float" and not (isinstance(v, int | float) and v > 0):
                raise AnalysisError(f"group key {f.name} = {v!r}: must be a number > 0")


@dataclass(frozen=True)
class Group:
    id: int
    key: GroupKey
    base_feed_mm_min: float
    rule_name: str
    rule_toml: str
    note: str
    created_utc: str

    @property
    def rule(self) -> FeedRule:
        return rule_from_toml(self.rule_toml, f"rule base group {self.id}")

    def summary(self) -> JsonObject:
        return {
            "id": self.id,
            **asdict(self.key),
            "base_feed_mm_min": self.base_feed_mm_min,
            "rule": self.rule_name,
            "note": self.note,
            "created_utc": self.created_utc,
        }


@dataclass(frozen=True)
class Match:
    group: Group
    exact: bool
    distance: float
    differences: dict[str, tuple[str | float, str | float]]  # field -> (asked, found)

    def statement(self) -> str:
        if self.exact:
            return f"exact match: group {self.group.id} ({self.group.rule_name})"
        diffs = ", ".join(f"{k} {a} -> {b}" for k, (a, b) in self.differences.items())
        return (
            f"nearest match: group {self.group.id} ({self.group.rule_name}), distance "
            f"{self.distance:.3f}; differs in {diffs}"
        )


def default_path() -> Path:
    """Rule base path: ``$CUTLAB_RULEBASE``, else ``rulebase_path`` of ``configs/lab.toml``."""
    env = os.environ.get("CUTLAB_RULEBASE")
    if env:
        return Path(env)
    lab = config_dir() / "lab.toml"
    if lab.exists():
        data, _ = read_toml(lab)
        p = data.get("rulebase_path")
        if not isinstance(p, str) or not p:
            raise ConfigError(f"{lab}: rulebase_path = {p!r}: expected a path string")
        q = Path(p)
        return q if q.is_absolute() else REPO_ROOT / q
    return REPO_ROOT / "data" / "rulebase.sqlite"


class RuleBase:
    """The SQLite rule base. Use as a context manager or call :meth:`close`."""

    def __init__(
        self, path: str | Path | None = None, timeout_s: float = 30.0, *, create: bool = True
    ) -> None:
        """Open the rule base at ``path`` (default :func:`default_path`). ``create=False``
        refuses a file that does not exist instead of creating an empty base there (a mistyped
        path must not read as an empty base)."""
        self.path = Path(path) if path is not None else default_path()
        if not create and not self.path.is_file():
            raise ConfigError(
                f"{self.path}: no rule base here (no such file); `cutlab rules add` creates it"
            )
        self.path.parent.mkdir(parents=True, exist_ok=True)
        try:
            self._con = sqlite3.connect(self.path, timeout=timeout_s, isolation_level=None)
            self._con.execute("PRAGMA journal_mode=WAL")
            self._con.execute("PRAGMA foreign_keys=ON")
            version = self._con.execute("PRAGMA user_version").fetchone()[0]
            if version == 0:
                with self._tx():
                    self._con.execute(_SCHEMA)  # one statement: executescript would commit
                    self._con.execute(f"PRAGMA user_version={SCHEMA_VERSION}")
            elif version != SCHEMA_VERSION:
                raise ConfigError(
                    f"{self.path}: rule base schema version {version}, this cutlab reads "
                    f"{SCHEMA_VERSION}"
                )
        except sqlite3.DatabaseError as exc:
            raise ConfigError(f"{self.path}: not a cutlab rule base (SQLite: {exc})") from None

    def __enter__(self) -> RuleBase:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._con.close()

    @contextmanager
    def _tx(self) -> Iterator[sqlite3.Connection]:
        """One IMMEDIATE transaction: all of it lands or none of it does."""
        self._con.execute("BEGIN IMMEDIATE")
        try:
            yield self._con
        except BaseException:
            self._con.execute("ROLLBACK")
            raise
        self._con.execute("COMMIT")

    # -- writing ------------------------------------------------------------------------------

    def add(self, key: GroupKey, rule: FeedRule, note: str = "", replace: bool = False) -> int:
        """Store ``rule`` for group ``key``; returns the group id. Existing key: error unless
        ``replace``."""
        text = rule_to_toml(rule)
        return self._insert(key, rule, text, note, replace)

    def import_file(
        self, path: str | Path, key: GroupKey, note: str = "", replace: bool = False
    ) -> int:
        """Validate a rule file (errors name file, field and value) and store it verbatim."""
        _, text = read_toml(path)
        rule = rule_from_toml(text, str(path))
        return self._insert(key, rule, text, note, replace)

    def _insert(self, key: GroupKey, rule: FeedRule, text: str, note: str, replace: bool) -> int:
        row = (
            *asdict(key).values(),
            rule.base_feed_mm_min,
            rule.name,
            text,
            note,
            _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        )
        cols = [f.name for f in fields(GroupKey)] + [
            "base_feed_mm_min",
            "rule_name",
            "rule_toml",
            "note",
            "created_utc",
        ]
        sql = f"INSERT INTO groups ({', '.join(cols)}) VALUES ({', '.join('?' * len(cols))})"
        if replace:  # an upsert keeps the group's id (INSERT OR REPLACE would give a new one)
            keys = ", ".join(f.name for f in fields(GroupKey))
            new = ", ".join(f"{c} = excluded.{c}" for c in cols[len(fields(GroupKey)) :])
            sql += f" ON CONFLICT ({keys}) DO UPDATE SET {new}"
        try:
            with self._tx() as con:
                return int(con.execute(sql + " RETURNING id", row).fetchone()[0])
        except sqlite3.IntegrityError:
            same = [g for g in self._rows("WHERE operation = ?", (key.operation,)) if g.key == key]
            raise GroupExistsError(self.path, key, same[0].id if same else -1) from None

    def remove(self, group_id: int) -> None:
        with self._tx() as con:
            if con.execute("DELETE FROM groups WHERE id = ?", (group_id,)).rowcount == 0:
                raise AnalysisError(f"{self.path}: no group with id {group_id}")

    # -- reading ------------------------------------------------------------------------------

    def _rows(self, where: str = "", args: tuple[object, ...] = ()) -> list[Group]:
        cols = [f.name for f in fields(GroupKey)]
        q = (
            f"SELECT id, {', '.join(cols)}, base_feed_mm_min, rule_name, rule_toml, note, "
            f"created_utc FROM groups {where} ORDER BY id"
        )
        out = []
        for r in self._con.execute(q, args):
            key = GroupKey(*r[1 : 1 + len(cols)])
            out.append(Group(r[0], key, *r[1 + len(cols) :]))
        return out

    def list(self) -> list[Group]:
        return self._rows()

    def get(self, group_id: int) -> Group:
        rows = self._rows("WHERE id = ?", (group_id,))
        if not rows:
            raise AnalysisError(f"{self.path}: no group with id {group_id}")
        return rows[0]

    def find(self, name: str) -> Group:
        """A group by its rule name (or id given as a string)."""
        if name.isascii() and name.isdigit():  # not "²": str.isdigit takes superscripts
            return self.get(int(name))
        rows = self._rows("WHERE rule_name = ?", (name,))
        if not rows:
            known = sorted({g.rule_name for g in self.list()})
            raise AnalysisError(f"{self.path}: no rule named '{name}'; known: {known}")
        if len(rows) > 1:
            raise AnalysisError(
                f"{self.path}: rule name '{name}' is used by groups {[g.id for g in rows]}: "
                "give the id"
            )
        return rows[0]

    def lookup(self, key: GroupKey, exact_only: bool = False) -> Match:
        """The group for ``key``: exact, else nearest of the same operation and material."""
        cands = self._rows("WHERE operation = ? AND material = ?", (key.operation, key.material))
        for g in cands:
            if g.key == key:
                return Match(g, True, 0.0, {})
        if not cands:
            have = sorted({(g.key.operation, g.key.material) for g in self.list()})
            raise AnalysisError(
                f"{self.path}: no rule for operation '{key.operation}' and material "
                f"'{key.material}'; the base has (operation, material): {have}"
            )

        def dist(g: Group) -> float:
            d: float = sum(
                w * abs(getattr(g.key, f) - getattr(key, f)) / getattr(key, f)
                for f, w in _WEIGHTS.items()
            )
            return d + (_FAMILY_WEIGHT if g.key.part_family != key.part_family else 0.0)

        best = min(cands, key=lambda g: (dist(g), g.id))
        diffs = {
            f.name: (getattr(key, f.name), getattr(best.key, f.name))
            for f in fields(GroupKey)
            if getattr(key, f.name) != getattr(best.key, f.name)
        }
        if exact_only:
            raise AnalysisError(f"{self.path}: {_no_exact(key, cands, best, diffs)}")
        return Match(best, False, dist(best), diffs)

    def for_tool(
        self, tool: str, material: str, tool_diameter_mm: float, flute_length_mm: float
    ) -> Match | None:
        """The rule of tool ``tool`` in ``material`` when no rule is named (issue 28): a group
        whose rule was derived with that tool, else one keyed by the same tool diameter and
        flute length (seed 001's tool identity; stated as a substitution), the newest first;
        None when the base has neither (the tool keeps its feeds)."""
        cands = self._rows("WHERE material = ?", (material,))[::-1]  # the newest first
        own = [g for g in cands if g.rule.tool == tool]
        if own:
            return Match(own[0], True, 0.0, {})
        same = [
            g for g in cands
            if abs(g.key.tool_diameter_mm - tool_diameter_mm) <= 1e-6 * tool_diameter_mm
            and abs(g.key.flute_length_mm - flute_length_mm) <= 1e-6 * flute_length_mm
        ]  # fmt: skip
        if not same:
            return None
        return Match(same[0], False, 0.0, {"tool": (tool, same[0].rule.tool or "unnamed")})

    def export(self, group_id: int, path: str | Path) -> Path:
        """Write a group's rule file exactly as stored."""
        g = self.get(group_id)
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(g.rule_toml, encoding="utf-8")
        return p

    def integrity_ok(self) -> bool:
        return bool(self._con.execute("PRAGMA integrity_check").fetchone()[0] == "ok")


def _no_exact(
    key: GroupKey, cands: list[Group], best: Group, diffs: dict[str, tuple[object, object]]
) -> str:
    """Why an exact lookup failed: each key field in which the nearest group differs, with the
    values the base holds for it among the groups of the same operation and material."""
    where = f"{key.operation}/{key.material}"
    parts = []
    for f in diffs:
        have = sorted({getattr(g.key, f) for g in cands})
        parts.append(f"{f} = {_fmt(getattr(key, f))} (the base has {', '.join(map(_fmt, have))})")
    return (
        f"no rule for {'; '.join(parts)} among the {len(cands)} {where} group(s); nearest: "
        f"group {best.id} ({best.rule_name}) with "
        + ", ".join(f"{f} = {_fmt(b)}" for f, (_, b) in diffs.items())
    )
