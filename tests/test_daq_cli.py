"""`cutlab daq record`, `cutlab data info`, `cutlab data plot` end to end on real files."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from analysis import runfile as rf
from rig.cli import main

ROOT = Path(__file__).resolve().parent.parent


def _json(capsys, argv: list[str]) -> dict:
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_record_info_plot(tmp_path: Path, capsys) -> None:
    out = tmp_path / "run.h5"
    cond = '{"feed_mm_min": 300, "tool": "phi10-flat"}'
    rec = _json(capsys, ["daq", "record", "--sim", "--seconds", "0.5", "--rate-hz", "10000",
                         "--speed", "0", "--quiet", "--sim-overflow-at", "1234", "-o", str(out),
                         "--conditions", cond, "--json"])  # fmt: skip
    assert rec["status"] == "success" and rec["channels"] == ["Fx", "Fy", "Fz"]
    assert rec["samples_acquired"] == 5000 and rec["samples_missing"] == 1000
    info = _json(capsys, ["data", "info", str(out), "--json"])
    assert info["complete"] and info["rate_hz"] == 10000.0
    assert info["samples_stored"] == 4000 and info["duration_s"] == pytest.approx(0.5)
    assert info["gaps"] == [
        {"kind": "gap", "sample": 1234, "lost": 1000, "time_s": 0.1234,
         "message": "1000 samples missing"}
    ]  # fmt: skip
    assert info["events"]["overflow"] == 1
    assert info["conditions"] == {"feed_mm_min": 300, "tool": "phi10-flat"}
    assert info["calibration_id"] == "9257B-example-sheet"
    assert main(["data", "info", str(out)]) == 0
    table = capsys.readouterr().out
    assert "samples_lost" in table and "1234" in table
    png = tmp_path / "forces.png"
    assert main(["data", "plot", str(out), "-o", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # The recorded signal is the synthetic milling force: calibrated back to ~N, not volts.
    run = rf.load_run(out)
    assert 50 < run.force_n[:, 0].mean() < 250


def test_record_raw_and_uncalibrated_channels(tmp_path: Path, capsys) -> None:
    out = tmp_path / "eight.h5"
    rec = _json(capsys, ["daq", "record", "--sim", "--seconds", "0.2", "--rate-hz", "5000",
                         "--channels", "8", "--raw", "--speed", "0", "--quiet", "-o", str(out),
                         "--json"])  # fmt: skip
    assert rec["channels"] == [f"sim/ai{i}" for i in range(8)]
    run = rf.load_run(out)
    assert run.force_n is None and run.raw.shape == (1000, 8)
    assert np.all(np.isfinite(run.volts))


def test_bad_rig_config_is_one_line_exit_2(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "rig.toml"
    text = (ROOT / "configs" / "rig.toml").read_text()
    two = "crosstalk = [[1.0, 0.0], [0.0, 1.0]]"
    bad_text = re.sub(r"(?m)^crosstalk\s*=.*$", two, text)
    assert bad_text != text
    bad.write_text(bad_text)
    code = main(["daq", "record", "--sim", "--seconds", "0.1", "--rig", str(bad), "--quiet",
                 "-o", str(tmp_path / "x.h5")])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and "crosstalk is 2 x [2]: expected 3 x 3" in err and str(bad) in err
    assert not (tmp_path / "x.h5").exists()


def test_existing_file_needs_force(tmp_path: Path, capsys) -> None:
    out = tmp_path / "keep.h5"
    out.write_bytes(b"precious")
    code = main(["daq", "record", "--sim", "--seconds", "0.1", "--quiet", "-o", str(out)])
    assert code == 2 and "file exists" in capsys.readouterr().err
    assert out.read_bytes() == b"precious"


def test_real_device_missing_is_explained(tmp_path: Path, capsys) -> None:
    out = tmp_path / "hw.h5"
    code = main(["daq", "record", "--seconds", "0.1", "--quiet", "-o", str(out)])
    err = capsys.readouterr().err
    if code == 0:  # pragma: no cover - NI hardware present
        pytest.skip("an NI device answered")
    assert code == 2 and "NI-DAQmx" in err and "--sim" in err
    assert len(err.strip().splitlines()) == 1
    assert not out.exists()  # no empty run left behind
