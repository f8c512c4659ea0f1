"""`cutlab nc check|motions|plot`, run in-process through the CLI."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from planning.nc import Program, interpret, motion_stats, segment_time_s
from rig.cli import main

SAMPLE = Path(__file__).resolve().parents[1] / "data" / "programs" / "demo-part.nc"


def test_check_json(capsys):
    assert main(["nc", "check", str(SAMPLE), "--json", "--machine", "ace-h63"]) == 0
    out = json.loads(capsys.readouterr().out)
    m = interpret(Program.read(SAMPLE))
    assert out["blocks"] == len(Program.read(SAMPLE)) and out["motions"] == len(m)
    from analysis.config import load_machine

    st = motion_stats(m, load_machine("ace-h63"))
    assert out["time_s"] == pytest.approx(st.time_s)
    assert out["time_s"] == pytest.approx(segment_time_s(m, load_machine("ace-h63")).sum())
    assert out["cutting_length_mm"] == pytest.approx(st.cutting_length_mm)
    assert out["bbox"]["min_mm"] == pytest.approx([-40, -35, -12])
    assert out["warnings"] == []


def test_check_table_and_lenient_warnings(tmp_path, capsys):
    p = tmp_path / "odd.nc"
    p.write_text("G0 X1\nM99\nG1 X2 F100\n")
    assert main(["nc", "check", str(p)]) == 2
    assert "unknown M-code M99" in capsys.readouterr().err
    assert main(["nc", "check", str(p), "--lenient"]) == 0
    cap = capsys.readouterr()
    assert "cutting_length_mm" in cap.out and f"{p}:2:1: 'M99'" in cap.err
    for cmd in (["motions", "--csv"], ["plot", "-o", str(tmp_path / "odd.png")]):
        assert main(["nc", cmd[0], str(p), "--lenient", *cmd[1:]]) == 0
        assert f"warning: {p}:2:1: 'M99'" in capsys.readouterr().err  # not dropped


def test_motions_csv(tmp_path, capsys):
    assert main(["nc", "motions", str(SAMPLE), "--csv"]) == 0
    df = pd.read_csv(io.StringIO(capsys.readouterr().out))
    m = interpret(Program.read(SAMPLE))
    assert len(df) == len(m)
    assert list(df.columns[:12]) == [
        "line", "block", "kind", "x0", "y0", "z0", "x1", "y1", "z1", "cx", "cy", "cz",
    ]  # fmt: skip
    np.testing.assert_allclose(df[["x1", "y1", "z1"]].to_numpy(), m.end, atol=1e-4)
    np.testing.assert_array_equal(df["line"], m.line)
    assert {"rapid", "line", "arc_ccw", "dwell"} <= set(df["kind"])
    out = tmp_path / "m.csv"
    assert main(["nc", "motions", str(SAMPLE), "-o", str(out)]) == 0
    assert len(pd.read_csv(out)) == len(m)


def test_plot_png(tmp_path, capsys):
    out = tmp_path / "sub" / "path.png"
    assert main(["nc", "plot", str(SAMPLE), "-o", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 20_000
    assert "wrote" in capsys.readouterr().err
