"""`cutlab daq record`, `cutlab data info`, `cutlab data plot` end to end on real files."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from analysis.runs import file as rf
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
    err = capsys.readouterr().err
    assert code == 2 and err.strip() == f"cutlab: error: {out}: file exists; --force overwrites it"
    assert out.read_bytes() == b"precious"
    rec = _json(capsys, ["daq", "record", "--sim", "--seconds", "0.1", "--speed", "0", "--quiet",
                         "-o", str(out), "--force", "--json"])  # fmt: skip
    assert rec["status"] == "success" and rf.load_run(out).samples_stored == 2000


def test_conditions_as_key_value_pairs(tmp_path: Path, capsys) -> None:
    """The same KEY=VALUE form as `cutlab analyze forces --conditions`; numbers stay numbers."""
    out = tmp_path / "kv.h5"
    _json(capsys, ["daq", "record", "--sim", "--seconds", "0.1", "--speed", "0", "--quiet",
                   "-o", str(out), "--conditions", "spindle_rpm=600", "fz_mm=0.236",
                   "tool=phi10-flat", "--json"])  # fmt: skip
    cond = rf.load_run(out, samples=False).conditions
    assert cond == {"spindle_rpm": 600, "fz_mm": 0.236, "tool": "phi10-flat"}
    assert isinstance(cond["spindle_rpm"], int) and isinstance(cond["fz_mm"], float)


@pytest.mark.parametrize(
    ("items", "match"),
    [
        (["spindle_rpm"], "--conditions 'spindle_rpm': expected KEY=VALUE"),
        (["=600"], "--conditions '=600': expected KEY=VALUE"),
        (["a=1", "a=2"], "--conditions: a given twice"),
        (['{"a": 1'], "not a JSON object"),
        (["[1, 2]"], "expected KEY=VALUE"),
    ],
)
def test_bad_conditions_are_one_line(tmp_path: Path, capsys, items, match) -> None:
    out = tmp_path / "bad.h5"
    code = main(["daq", "record", "--sim", "--seconds", "0.1", "--speed", "0", "--quiet",
                 "-o", str(out), "--conditions", *items])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and match in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_rate_below_twice_the_highest_mode_warns(tmp_path: Path, capsys) -> None:
    """configs/rig.toml: 9257B modes 2050/1810/3230 Hz (seed 003 Table 2) -> >= 6460 Hz."""
    low = tmp_path / "low.h5"
    assert main(["daq", "record", "--sim", "--seconds", "0.1", "--rate-hz", "2000", "--speed",
                 "0", "--quiet", "-o", str(low)]) == 0  # fmt: skip
    err = capsys.readouterr().err
    warn = [ln for ln in err.splitlines() if "warning" in ln]
    assert len(warn) == 1 and "2000 Hz" in warn[0] and "z 3230 Hz" in warn[0]
    assert ">= 6460 Hz" in warn[0]
    notes = rf.load_run(low, samples=False).events.query("kind == 'note'")
    assert list(notes["message"]) == [warn[0].removeprefix("daq record: ")]
    assert list(notes["sample"]) == [0]
    ok = tmp_path / "ok.h5"
    assert main(["daq", "record", "--sim", "--seconds", "0.1", "--rate-hz", "6460", "--speed",
                 "0", "--quiet", "-o", str(ok)]) == 0  # fmt: skip
    assert "warning" not in capsys.readouterr().err
    assert "note" not in set(rf.load_run(ok, samples=False).events["kind"])


def test_real_device_missing_is_explained(tmp_path: Path, capsys) -> None:
    out = tmp_path / "hw.h5"
    code = main(["daq", "record", "--seconds", "0.1", "--quiet", "-o", str(out)])
    err = capsys.readouterr().err
    if code == 0:  # pragma: no cover - NI hardware present
        pytest.skip("an NI device answered")
    assert code == 2 and "NI-DAQmx" in err and "--sim" in err
    assert len(err.strip().splitlines()) == 1
    assert not out.exists()  # no empty run left behind


def test_aliasing_warning_follows_the_configured_modes() -> None:
    from analysis.config import Mode, load_rig
    from rig.log.record import aliasing_warning

    dyno = load_rig().dynamometer
    assert aliasing_warning(6460.0, dyno) is None
    assert "6459.5 Hz" in aliasing_warning(6459.5, dyno)
    stiff = dyno.model_copy(
        update={"modes": (Mode(axis="x", frequency_hz=5000, damping_ratio=0.05),)}
    )
    msg = aliasing_warning(9999.0, stiff)
    assert "x 5000 Hz" in msg and ">= 10000 Hz" in msg
    assert aliasing_warning(100.0, dyno.model_copy(update={"modes": ()})) is None
    assert len(aliasing_warning(1e-3, dyno).encode()) <= rf.EVENT_MESSAGE_BYTES
