"""`cutlab analyze forces` on exported runs: JSON result, validation plot, exits 1 and 2."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from analysis.config import get_material, get_tool, load_rig
from analysis.identify import RunConditions
from analysis.identify.endmill import synthetic_endmill_run
from analysis.identify.facemill import synthetic_facemill_run
from analysis.modal import DynamometerFilter
from rig.cli import main


def _export(path: Path, run, extra: dict) -> None:
    """A DynoWare-style export (decimal comma) with the conditions in its header."""
    lines = ["DynoWare\tType 5697A", f"Sampling rate:\t{int(run.rate_hz)} Hz"]
    lines += [f"{k}:\t{str(v).replace('.', ',')}" for k, v in extra.items()]
    lines += ["", "Time\tFx\tFy\tFz", "s\tN\tN\tN"]
    t = np.arange(len(run.force_n)) / run.rate_hz
    lines += [
        "\t".join(f"{v:.5f}".replace(".", ",") for v in row)
        for row in np.column_stack([t, run.force_n])
    ]
    path.write_text("\n".join(lines) + "\n")


@pytest.fixture(scope="module")
def exports(tmp_path_factory):
    tool = get_tool("seed003-facemill")
    coef = get_material("al6061-t6").facemill
    # The records pass through the rig's modes (those a 5 kHz record can show).
    modes = DynamometerFilter.from_config(load_rig().dynamometer, 5000.0, crosstalk=False,
                                          drop_above_nyquist=True)  # fmt: skip
    d0 = tmp_path_factory.mktemp("exports")
    rng = np.random.default_rng(4)
    files = []
    for fz, depths in ((0.236, (0.5, 1.5, 3.0)), (0.345, (1.0,))):
        for d in depths:
            c = RunConditions(spindle_rpm=600, fz_mm=fz, depth_mm=d, width_mm=100.0)
            run = synthetic_facemill_run(
                "r", tool, coef, c, 5000.0, cut_s=1.5, rng=rng, noise_frac=0.01, phase_rad=d,
                dynamometer=modes,
            )  # fmt: skip
            p = d0 / f"fz{fz}_d{d}.txt"
            _export(p, run, {"tool": "seed003-facemill", "spindle_rpm": 600, "fz_mm": fz,
                             "depth_mm": d, "width_mm": 100})  # fmt: skip
            files.append(p)
    return files


@pytest.mark.long
def test_forces_json_and_validation(exports, tmp_path, capsys):
    fit_files, other = exports[:3], exports[3]
    rc = main(["analyze", "forces", *map(str, fit_files), "--validate", str(other),
               "--plot", str(tmp_path), "--json"])  # fmt: skip
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["success"] and out["model"] == "facemill", out["message"]
    assert out["coefficients"]["K_T_n_mm2"] == pytest.approx(405.4, rel=0.03)
    assert out["statistics"]["K_R"]["std_error"] > 0
    assert out["validation"]["max_error_pct"] < 3
    assert len(out["plots"]) == 2 and all(Path(p).stat().st_size > 10_000 for p in out["plots"])


def test_forces_too_few_runs_exits_1(exports, capsys):
    rc = main(["analyze", "forces", str(exports[0]), str(exports[1])])
    captured = capsys.readouterr()
    assert rc == 1 and "too few runs" in captured.out


def test_forces_bad_input_exits_2(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("Time [s]\tFx [N]\tFy [lbf]\tFz [N]\n0\t1\t2\t3\n0.001\t1\t2\t3\n"
                   "0.002\t1\t2\t3\n0.003\t1\t2\t3\n")  # fmt: skip
    rc = main(["analyze", "forces", str(bad), "--tool", "seed003-facemill",
               "--conditions", "spindle_rpm=600", "fz_mm=0.2", "depth_mm=1"])  # fmt: skip
    err = capsys.readouterr().err
    assert rc == 2 and "mixed units" in err and "Traceback" not in err
    rc = main(["analyze", "forces", str(bad), "--model", "endmill", "--tool", "seed003-facemill"])
    assert rc == 2


def _export_csv(path: Path, run, header: dict) -> None:
    """A plain CSV export: ``key: value`` header lines, then time_s and the three forces."""
    lines = [f"{k}: {v}" for k, v in header.items()] + ["time_s,Fx,Fy,Fz"]
    t = np.arange(len(run.force_n)) / run.rate_hz
    lines += [",".join(f"{v:.6g}" for v in row) for row in np.column_stack([t, run.force_n])]
    path.write_text("\n".join(lines) + "\n")


ENDMILL_FEEDS = (0.03, 0.05, 0.08, 0.1)


@pytest.fixture(scope="module")
def slot_exports(tmp_path_factory):
    """Slots with the README's phi10-flat at 3000 rpm, 2 mm deep; each export's header gives its
    own fz_mm and a depth_mm of 5 that --conditions depth_mm=2 must override."""
    tool = get_tool("phi10-flat")
    truth = get_material("al6061-t6").endmill
    modes = DynamometerFilter.from_config(load_rig().dynamometer, 10_000.0, crosstalk=False)
    d0 = tmp_path_factory.mktemp("slots")
    rng = np.random.default_rng(8)
    files = []
    for fz in ENDMILL_FEEDS:
        c = RunConditions(spindle_rpm=3000, fz_mm=fz, depth_mm=2.0, width_mm=10.0, mode="slot")
        run = synthetic_endmill_run("s", tool, truth, c, 10_000.0, cut_s=1.0, air_s=0.3,
                                    noise_frac=0.01, dynamometer=modes, rng=rng,
                                    offset_n=rng.normal(0, 3, 3))  # fmt: skip
        p = d0 / f"slot_{fz}.csv"
        _export_csv(p, run, {"fz_mm": fz, "depth_mm": 5})
        files.append(p)
    return truth, files


@pytest.mark.long
def test_endmill_readme_example_merges_conditions_with_each_header(slot_exports, capsys):
    truth, files = slot_exports
    rc = main(["analyze", "forces", *map(str, files), "--model", "endmill", "--tool",
               "phi10-flat", "--conditions", "spindle_rpm=3000", "depth_mm=2", "mode=slot",
               "--keep", "--json"])  # fmt: skip (--keep: fz 0.1 > phi10-flat's max chip 0.08)
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["success"] and out["model"] == "endmill", out["message"]
    # Each run keeps its own header feed; --conditions replaced the header's depth.
    assert [r["fz_mm"] for r in out["per_run"]] == list(ENDMILL_FEEDS)
    assert {r["depth_mm"] for r in out["per_run"]} == {2.0}
    got = out["coefficients"]
    for name in ("Ktc_n_mm2", "Krc_n_mm2", "Kac_n_mm2", "Kte_n_mm", "Kre_n_mm"):
        assert got[name] == pytest.approx(getattr(truth, name), rel=0.02), name
    assert got["Kae_n_mm"] == pytest.approx(truth.Kae_n_mm, abs=0.2)


@pytest.mark.long
def test_condition_missing_from_header_and_flags_names_file_and_key(slot_exports, capsys):
    _, files = slot_exports
    rc = main(["analyze", "forces", *map(str, files), "--tool", "phi10-flat",
               "--conditions", "depth_mm=2", "mode=slot"])  # fmt: skip
    err = capsys.readouterr().err
    assert rc == 2 and "Traceback" not in err
    assert "slot_0.03.csv" in err and "'spindle_rpm'" in err


def test_forces_table_footer_says_what_the_intervals_cover(exports, capsys):
    rc = main(["analyze", "forces", *map(str, exports[:3])])
    out = capsys.readouterr().out
    assert rc == 0 and "ci_high" in out
    assert "measurement noise only" in out and "model error" in out


def test_export_cut_with_another_tool_is_refused(exports, capsys):
    rc = main(["analyze", "forces", *map(str, exports[:3]), "--tool", "phi10-flat"])
    err = capsys.readouterr().err
    assert rc == 2 and "fz0.236_d0.5.txt" in err
    assert "'seed003-facemill'" in err and "'phi10-flat'" in err
    assert "too few runs" not in err


def test_validation_run_of_another_tool_is_refused(exports, tmp_path, capsys):
    other = tmp_path / "other_tool.txt"
    text = exports[3].read_text()
    assert "tool:\tseed003-facemill" in text
    other.write_text(text.replace("tool:\tseed003-facemill", "tool:\tphi10-flat"))
    rc = main(["analyze", "forces", *map(str, exports[:3]), "--validate", str(other)])
    err = capsys.readouterr().err
    assert rc == 2 and "other_tool.txt" in err and "the fitted runs' tool" in err
