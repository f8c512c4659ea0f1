"""`cutlab analyze forces` on exported runs: JSON result, validation plot, exits 1 and 2."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from analysis._identify import RunConditions
from analysis.config import get_material, get_tool, load_rig
from analysis.dynamics import DynamometerFilter
from analysis.identify_facemill import synthetic_facemill_run
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
