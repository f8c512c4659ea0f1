"""Write (or ``--check``) docs/configuration.md, the reference of every config file's keys,
generated from the config models: ``python -m rig.cli.configref [--check]``."""

# Not a cutlab command: it lives outside rig.cli; rig/cli/configref.py keeps the documented
# `python -m rig.cli.configref` running it.

from __future__ import annotations

import argparse
import sys
from pathlib import Path

DOC = Path(__file__).resolve().parents[1] / "docs" / "configuration.md"


def files() -> list[tuple[str, str, type]]:
    """(file pattern, what it is, model) of every config file cutlab reads."""
    from analysis.config import MachineConfig, MaterialLibrary, RigConfig, ToolLibrary
    from analysis.rules.rule import _RuleFile
    from planning.orient.config import OrientConfig
    from planning.rough.part import PartConfig
    from planning.stock.plans import _PlanModel
    from rig.campaign.schema import CampaignFile

    return [
        ("configs/machines/*.toml", "A machine: travel, feeds, spindle, dialect, serial link.",
         MachineConfig),
        ("configs/tools.toml", "The tool library (`[tools.<name>]`, `kind` picks the fields).",
         ToolLibrary),
        ("configs/materials.toml", "Materials and the simulated rig's true coefficients.",
         MaterialLibrary),
        ("configs/rig.toml", "The dynamometer, its amplifiers and the DAQ task.", RigConfig),
        ("configs/campaigns/*.toml", "A campaign of test cuts (`cutlab campaign run`).",
         CampaignFile),
        ("configs/parts/*.toml", "A part for Z-level roughing (`cutlab plan rough`).",
         PartConfig),
        ("configs/orient/*.toml", "A 5-axis orientation job (`cutlab plan orient`).",
         OrientConfig),
        ("data/plans/*.toml", "An operation plan (`cutlab plan simulate`); its `[stock]` table "
         "is also what a `--stock` TOML holds.", _PlanModel),
        ("feed rule files (`cutlab rules derive -o`)", "A 20-bin feed rule (seed 001).",
         _RuleFile),
    ]  # fmt: skip


def render() -> str:
    from analysis.validation import reference_markdown

    return reference_markdown(files())


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m rig.cli.configref", description=__doc__)
    p.add_argument("--check", action="store_true", help="exit 1 if the file is not current")
    args = p.parse_args(argv)
    text = render()
    if args.check:
        current = DOC.exists() and DOC.read_text(encoding="utf-8") == text
        if not current:
            print(f"{DOC} is out of date: run python -m rig.cli.configref", file=sys.stderr)
        return 0 if current else 1
    DOC.parent.mkdir(exist_ok=True)
    DOC.write_text(text, encoding="utf-8")
    print(f"wrote {DOC}", file=sys.stderr)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
