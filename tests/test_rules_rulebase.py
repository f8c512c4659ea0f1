"""The SQLite rule base: keys, lookup, import/export, concurrency and a killed writer."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from analysis.errors import AnalysisError, ConfigError
from analysis.rules import GroupExistsError, GroupKey, RuleBase, slot_load_percent
from analysis.rules.rule import derive_rule, rule_to_toml, save_rule

ROOT = Path(__file__).resolve().parent.parent


def _key(**kw) -> GroupKey:
    base = dict(
        part_family="trunk/outer/draw/lower-die",
        operation="roughing",
        tool_diameter_mm=50.0,
        flute_length_mm=40.0,
        material="FC30",
        spindle_rpm=1000.0,
        depth_mm=0.5,
        tolerance_mm=0.1,
    )
    base.update(kw)
    return GroupKey(**base)


def _rule(name: str, base: float = 600.0):
    return derive_rule(name, 100, base, 3500, slot_load_percent("flat", 50, 0.5, 40))


@pytest.fixture()
def db(tmp_path):
    with RuleBase(tmp_path / "rules.sqlite") as rb:
        # Seed 001 Table 1.
        rb.add(_key(), _rule("abc", 600))
        rb.add(
            _key(
                operation="pencil",
                tool_diameter_mm=32,
                flute_length_mm=30,
                spindle_rpm=1200,
                tolerance_mm=0.05,
            ),
            _rule("bca", 500),
        )
        rb.add(
            _key(
                operation="rest-roughing",
                tool_diameter_mm=16,
                flute_length_mm=30,
                spindle_rpm=2500,
                tolerance_mm=0.05,
            ),
            _rule("cab", 1500),
        )
        yield rb


def test_exact_and_nearest_lookup(db) -> None:
    m = db.lookup(_key())
    assert m.exact and m.group.rule_name == "abc" and m.group.base_feed_mm_min == 600
    near = db.lookup(_key(tool_diameter_mm=40.0, part_family="hood/inner"))
    assert not near.exact and near.group.rule_name == "abc"
    assert near.differences == {
        "part_family": ("hood/inner", "trunk/outer/draw/lower-die"),
        "tool_diameter_mm": (40.0, 50.0),
    }
    assert (
        "nearest match" in near.statement() and "tool_diameter_mm 40.0 -> 50.0" in near.statement()
    )
    with pytest.raises(
        AnalysisError, match="no rule for operation 'roughing' and material 'SKD11'"
    ):
        db.lookup(_key(material="SKD11"))


def test_exact_lookup_names_the_key_fields_that_differ(db) -> None:
    """--exact with no exact row: the message names each differing key field, the asked value and
    the values the base holds for the same operation/material, not just (operation, material)."""
    db.add(_key(tool_diameter_mm=30.0), _rule("abc30", 650))
    with pytest.raises(AnalysisError) as err:
        db.lookup(_key(tool_diameter_mm=32.0), exact_only=True)
    msg = str(err.value)
    assert "no rule for tool_diameter_mm = 32 (the base has 30, 50)" in msg
    assert "2 roughing/FC30 group(s)" in msg
    assert "nearest: group 4 (abc30) with tool_diameter_mm = 30" in msg
    assert "the base has (operation, material)" not in msg and "\n" not in msg
    # Two fields off: both named, each with what the base has; untouched fields are not named.
    with pytest.raises(AnalysisError) as err:
        db.lookup(_key(tool_diameter_mm=32.0, depth_mm=0.8), exact_only=True)
    msg = str(err.value)
    assert "tool_diameter_mm = 32 (the base has 30, 50); depth_mm = 0.8 (the base has 0.5)" in msg
    assert "spindle_rpm" not in msg and "part_family" not in msg
    # Without --exact the same key gives the nearest match, stated.
    assert db.lookup(_key(tool_diameter_mm=32.0)).group.rule_name == "abc30"


def test_duplicate_key_rejected_unless_replace(db) -> None:
    with pytest.raises(GroupExistsError, match="group 1 has this key already") as err:
        db.add(_key(), _rule("again"))
    assert err.value.group_id == 1 and "use replace" not in str(err.value)
    assert db.add(_key(), _rule("again", 700), replace=True) == 1  # the group keeps its id
    assert db.get(1).base_feed_mm_min == 700
    assert db.lookup(_key()).group.rule_name == "again"
    assert len(db.list()) == 3


def test_import_export_is_byte_exact(db, tmp_path) -> None:
    src = save_rule(_rule("hand-made", 800), tmp_path / "in.toml")
    text = src.read_text() + "# edited by hand\n"
    src.write_text(text)
    gid = db.import_file(src, _key(operation="finishing"))
    out = db.export(gid, tmp_path / "out.toml")
    assert out.read_text() == text
    assert db.find("hand-made").rule.base_feed_mm_min == 800


def test_malformed_rule_file_rejected_with_file_field_value(db, tmp_path) -> None:
    text = rule_to_toml(_rule("bad"))
    p = tmp_path / "bad.toml"
    p.write_text(text.replace("max_feed_mm_min = 3500.0", "max_feed_mm_min = -5"))
    with pytest.raises(
        ConfigError, match=r"bad.toml:\d+: rule.max_feed_mm_min = -5: .*greater than 0"
    ):
        db.import_file(p, _key(operation="x"))
    assert len(db.list()) == 3  # nothing stored


def test_missing_file_refused_unless_create(tmp_path) -> None:
    p = tmp_path / "rulbase.sqlite"  # a typo of an existing base's name
    with pytest.raises(ConfigError, match=r"rulbase.sqlite: no rule base here \(no such file\)"):
        RuleBase(p, create=False)
    assert not p.exists()
    with RuleBase(p) as rb:  # the default creates it (what adding a rule needs)
        assert rb.list() == []
    with RuleBase(p, create=False) as rb:
        assert rb.integrity_ok()


def test_not_a_rulebase(tmp_path) -> None:
    p = tmp_path / "junk.sqlite"
    p.write_bytes(b"this is not sqlite at all" * 100)
    with pytest.raises(ConfigError, match="not a cutlab rule base"):
        RuleBase(p)


_WRITER = textwrap.dedent("""
    import sys
    sys.path.insert(0, {root!r})
    from analysis.rules import RuleBase, GroupKey
    from analysis.rules.rule import derive_rule, rule_to_toml
    rb = RuleBase({path!r})
    rule = derive_rule("w", 100, 600, 3500, 0.1)
    text = rule_to_toml(rule)
    con = rb._con
    con.execute("BEGIN IMMEDIATE")
    for i in range(2000):
        con.execute(
            "INSERT INTO groups (part_family, operation, tool_diameter_mm, flute_length_mm, "
            "material, spindle_rpm, depth_mm, tolerance_mm, base_feed_mm_min, rule_name, "
            "rule_toml, created_utc) VALUES ('f', 'killed', ?, 30, 'm', 1000, 0.5, 0.1, 600, "
            "'w', ?, 'now')", (i + 1.0, text))
    print("inserted", flush=True)
    sys.stdin.read()  # wait to be killed mid-transaction
""")


def test_killed_writer_leaves_base_as_before(db) -> None:
    before = [g.id for g in db.list()]
    proc = subprocess.Popen(
        [sys.executable, "-c", _WRITER.format(root=str(ROOT), path=str(db.path))],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout.readline().strip() == "inserted"
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    with RuleBase(db.path) as rb2:
        assert rb2.integrity_ok()
        assert [g.id for g in rb2.list()] == before
        rb2.add(_key(operation="after-kill"), _rule("ok"))  # the lock was released
        assert len(rb2.list()) == len(before) + 1


_READER = textwrap.dedent("""
    import sys
    sys.path.insert(0, {root!r})
    from analysis.rules import RuleBase
    rb = RuleBase({path!r})
    print("ready", flush=True)
    last, reads = 0, 0
    while last < 43 and reads < 5000:  # until the writer's last rule is seen (bounded)
        n = len(rb.list())
        assert n >= last, (n, last)
        for g in rb.list():
            g.rule  # every stored rule parses
        last, reads = n, reads + 1
    print(last, reads)
""")


def test_concurrent_readers_during_writes(db) -> None:
    readers = [
        subprocess.Popen(
            [sys.executable, "-c", _READER.format(root=str(ROOT), path=str(db.path))],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for _ in range(3)
    ]
    # Every reader has the base open before the first write, so its reads overlap the writes
    # (rather than fixed 60 rounds, most of which came after them); each reads until it has
    # seen the 43rd rule.
    for r in readers:  # each within 60 s: a reader that never opens the base fails, not hangs
        ready, _, _ = select.select([r.stdout], [], [], 60.0)
        assert ready, "a reader did not open the rule base within 60 s"
        assert r.stdout.readline().strip() == "ready", r.stderr.read()
    for i in range(40):
        db.add(_key(operation=f"op{i}"), _rule(f"r{i}"))
    for r in readers:
        out, err = r.communicate(timeout=120)
        assert r.returncode == 0, err
        assert int(out.split()[0]) == 43, out
    assert len(db.list()) == 43
