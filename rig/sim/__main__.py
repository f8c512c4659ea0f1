"""``python -m rig.sim tap TOOL AXIS OUT.csv``: tap the twin's own structure of a catalogue tool
(:func:`rig.sim.tap.tap_twin`), as the shipped tools' catalogue modes were measured (issue 28)."""

from __future__ import annotations

import argparse

from analysis.errors import ConfigError
from rig.sim.tap import tap_twin


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m rig.sim", description=__doc__)
    sub = ap.add_subparsers(dest="command", required=True)
    tap = sub.add_parser("tap", help="tap test of the twin's structure (tool-tip displacement)")
    tap.add_argument("tool", help="catalogue tool name")
    tap.add_argument("axis", choices=("x", "y"))
    tap.add_argument("out", help="CSV to write (cutlab analyze modal reads it)")
    tap.add_argument("--rate", type=float, default=12_800.0, help="Hz, sample rate")
    tap.add_argument("--seed", type=int, default=0, help="rng seed of the hits and the noise")
    tap.add_argument("--tools", default=None, help="tool catalogue (default configs/tools.toml)")
    a = ap.parse_args(argv)
    try:
        print(tap_twin(a.tool, a.axis, a.out, a.rate, a.seed, a.tools))
    except ConfigError as exc:
        print(f"python -m rig.sim tap: error: {exc}")
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
