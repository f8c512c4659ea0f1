"""Compare cutlab's NC interpreter (dialect "linuxcnc") with LinuxCNC's ``rs274`` on a folder of
programs: segment by segment (kinds, end points, arc centres, feeds, dwells, rotary axes).

Prints one line per program that differs (file:line, the field, ours vs rs274) and a summary
``N agree, M differ, K skipped`` (skipped: programs using what cutlab does not interpret or
model — O-word subroutines, parameters, expressions, cutter compensation, probing ... — with the
reason; ``--all`` lists them, and the programs that agree).
Needs ``/usr/bin/rs274`` (``apt-get install linuxcnc-uspace``).

    .venv/bin/python bench/nc_vs_rs274.py [FOLDER_OR_FILE ...] [--pattern '*.ngc'] [--all]

Default: the example programs LinuxCNC ships in /usr/share/linuxcnc/ncfiles and cutlab's own
tests/data/nc/rs274.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

import _rs274  # noqa: E402

DEFAULT = [Path("/usr/share/linuxcnc/ncfiles"), ROOT / "tests" / "data" / "nc" / "rs274"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("paths", nargs="*", type=Path, help="folders or program files")
    ap.add_argument("--pattern", default="*.ngc", help="file pattern in folders (recursive)")
    ap.add_argument("--all", action="store_true", help="also list those that agree or are skipped")
    args = ap.parse_args(argv)
    if not _rs274.available():
        print(f"rs274 not found at {_rs274.RS274}: {_rs274.INSTALL_HINT}", file=sys.stderr)
        return 2
    files: list[Path] = []
    for p in args.paths or DEFAULT:
        files.extend(sorted(p.rglob(args.pattern)) if p.is_dir() else [p])
    agree = differ = skipped = 0
    for f in files:
        try:
            out = _rs274.compare_file(f)
        except Exception as exc:  # noqa: BLE001 - a comparison tool: report and go on
            print(f"{f}: comparison failed: {type(exc).__name__}: {exc}")
            differ += 1
            continue
        if out.skipped:
            skipped += 1
        elif out.agree:
            agree += 1
        else:
            differ += 1
        if args.all or not (out.agree or out.skipped):
            print(out)
    print(f"{agree} agree, {differ} differ, {skipped} skipped")
    return 0 if differ == 0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
