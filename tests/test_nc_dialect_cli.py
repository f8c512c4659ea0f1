"""`cutlab nc check|motions|plot --dialect linuxcnc` (and `--machine linuxcnc`, shipped) interpret
as LinuxCNC's own ``rs274`` does, with no machine file of the user's: the differential tier's
programs (tests/data/nc/rs274), LinuxCNC's shipped examples inside cutlab's scope and the
project's own programs (data/programs), each through the same function the commands call
(:func:`planning.nc.check_program`), compared segment by segment with rs274's canonical calls.
"""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import _rs274
import pytest
from _rs274 import compare, motion_segments, out_of_scope, parse_canon

from planning.nc import NCError, check_program
from rig.cli import main

HERE = Path(__file__).parent
ROOT = HERE.parent
OWN = sorted((HERE / "data" / "nc" / "rs274").glob("*.ngc"))
SHIPPED = sorted((ROOT / "data" / "programs").glob("*.nc"))
NCFILES = Path("/usr/share/linuxcnc/ncfiles")
EXAMPLES = [NCFILES / n for n in ("3dtest.ngc", "arcspiral.ngc", "b-index.ngc", "cds.ngc",
                                  "skeleton.ngc", "tort.ngc")]  # fmt: skip

needs_rs274 = pytest.mark.skipif(
    not _rs274.available(), reason=f"LinuxCNC's rs274 not installed ({_rs274.INSTALL_HINT})"
)


def _agree(path: Path, **how) -> _rs274.Outcome:
    """Both interpreters on ``path``; where rs274 refuses a line, cutlab must refuse it too and
    agree on what came before (checked on the program cut before cutlab's error line)."""
    canon = parse_canon(_rs274.run_rs274(path))
    assert canon.segments, f"rs274 on {path}: {canon.error or 'no motion'}"
    try:
        motion = check_program(str(path), keep_motion=True, **how).motion
    except NCError as exc:
        if not canon.error:
            return _rs274.Outcome(str(path), False, field="error", ours=str(exc), theirs="none")
        line = int(re.match(re.escape(str(path)) + r":(\d+):", str(exc)).group(1))
        head = path.with_name(path.stem + ".head" + path.suffix)
        head.write_text("".join(path.read_text().splitlines(keepends=True)[: line - 1]))
        motion = check_program(str(head), keep_motion=True, **how).motion
    else:
        if canon.error:
            return _rs274.Outcome(str(path), False, field="error", ours="none",
                                  theirs=canon.error)  # fmt: skip
    return compare(motion_segments(motion), canon.segments, str(path))


@needs_rs274
@pytest.mark.parametrize("path", OWN + EXAMPLES + SHIPPED, ids=lambda p: p.name)
def test_dialect_linuxcnc_agrees_with_rs274_without_a_machine_file(path: Path, tmp_path) -> None:
    if not path.exists():
        pytest.skip(f"{path} is not in this LinuxCNC version")
    if path in SHIPPED:
        # the project's programs carry a Fanuc program number (O0001), which LinuxCNC reads as
        # a subroutine label: sent to LinuxCNC without it, as the GRBL sender sends them; and
        # standalone rs274 starts with block delete off where cutlab's default is on: the
        # deleted blocks are left out of its copy
        text = "".join(ln for ln in path.read_text().splitlines(keepends=True)
                       if not re.match(r"\s*(O\d+\s*(\(.*\))?\s*$|/)", ln))  # fmt: skip
        path = tmp_path / path.name
        path.write_text(text)
    why = out_of_scope(path) if path not in OWN else ""
    if why:
        pytest.skip(f"uses {why}")
    out = _agree(path, dialect="linuxcnc")
    assert out.agree, str(out)


@needs_rs274
@pytest.mark.parametrize("name", ["feed_order.ngc", "canned.ngc", "offsets.ngc"])
def test_the_shipped_linuxcnc_machine_interprets_the_same(name: str) -> None:
    path = HERE / "data" / "nc" / "rs274" / name
    assert _agree(path, machine="linuxcnc").agree
    # the default (Fanuc) reading of the same program does not agree: the dialect matters
    assert not _agree(path).agree


def test_motions_and_plot_take_the_dialect(tmp_path: Path, capsys) -> None:
    path = HERE / "data" / "nc" / "rs274" / "feed_order.ngc"
    feeds = {}
    for dialect in ("linuxcnc", "fanuc"):
        out = tmp_path / f"{dialect}.csv"
        assert main(["nc", "motions", str(path), "--dialect", dialect, "-o", str(out)]) == 0
        feeds[dialect] = [float(r["feed_mm_min"]) for r in csv.DictReader(out.open())
                          if r["feed_mm_min"] not in ("", "nan")]  # fmt: skip
    assert feeds["linuxcnc"] != feeds["fanuc"]  # F after G20 in the same block: inch/min there
    png = tmp_path / "p.png"
    assert main(["nc", "plot", str(path), "--dialect", "linuxcnc", "-o", str(png), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["motions"] > 0
    assert png.read_bytes()[:4] == b"\x89PNG"
