"""Docs that are true: the configuration reference is generated from the models and current,
and every file the README names exists."""

from __future__ import annotations

import re
from pathlib import Path

from rig import configref

ROOT = Path(__file__).resolve().parent.parent


def test_configuration_reference_is_current() -> None:
    assert configref.DOC.read_text(encoding="utf-8") == configref.render(), (
        "docs/configuration.md is out of date: run .venv/bin/python -m rig.cli.configref"
    )


def test_the_reference_names_every_key_of_every_model() -> None:
    text = configref.DOC.read_text(encoding="utf-8")
    for _, _, model in configref.files():
        for name in model.model_fields:
            assert f"| `{name}" in text, f"{model.__name__}.{name} is not in the reference"


# configs/..., data/..., docs/..., bench/..., tests/... and the package folders; not out/ (written
# by commands), not globs or placeholders (<yours>, NNN, *)
PATH = re.compile(r"(?<![\w/.-])((?:configs|data|docs|bench|tests|analysis|planning|rig)"
                  r"/[\w./-]*\w)")  # fmt: skip


#: what commands write (as out/ is): `cutlab campaign run feed-sweep` its runs, `cutlab rules add`
#: the rule base
WRITTEN = ("data/campaigns/", "data/rulebase.sqlite")


def readme_paths() -> list[str]:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    found = []
    for m in PATH.finditer(text):
        p = m.group(1)
        glob = text[m.end() : m.end() + 1] in ("*", "?", "[")  # data/x/slot_*.csv: stops at *
        if glob or any(c in p for c in "*<>") or "NNN" in p or "NAME" in p or p.startswith(WRITTEN):
            continue
        found.append(p)
    return sorted(set(found))


def test_every_file_the_readme_names_exists() -> None:
    paths = readme_paths()
    assert len(paths) > 20  # the pattern still finds them
    missing = [p for p in paths if not (ROOT / p).exists()]
    assert not missing, f"README.md names files that do not exist: {missing}"
