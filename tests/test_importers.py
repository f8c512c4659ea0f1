"""Importing DynoWare exports (decimal comma, header block) and plain CSV as runs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from analysis.config import Dynamometer, DynoChannel, FaceMill, FaceMillCoefficients
from analysis.errors import AnalysisError
from analysis.identify import RunConditions, import_run, read_force_table
from analysis.identify.facemill import fit_facemill_runs, synthetic_facemill_run

DATA = Path(__file__).parent / "data" / "analysis"


def test_dynoware_decimal_comma_with_header_block():
    t = read_force_table(DATA / "dynoware_de.txt")
    assert t.columns == ("Time", "Fx", "Fy", "Fz")
    assert t.decimal == "," and t.separator == "\t"
    assert t.rate_hz == 20_000.0
    np.testing.assert_allclose(t.data[3], [0.00015, 1000.5, -2000.25, 300.125])
    run = import_run(DATA / "dynoware_de.txt")
    assert run.conditions.fz_mm == pytest.approx(0.236)
    assert run.conditions.depth_mm == 2.0 and run.conditions.spindle_rpm == 600
    np.testing.assert_allclose(run.force_n[1], [10.5, -20.25, 3.125])


def test_plain_csv_rate_from_time_and_kn_converted():
    run = import_run(DATA / "plain.csv", {"spindle_rpm": 600, "fz_mm": 0.2, "depth_mm": 1})
    assert run.rate_hz == pytest.approx(1000.0)
    kn = import_run(DATA / "semicolon_kn.csv", {"spindle_rpm": 600, "fz_mm": 0.2, "depth_mm": 1})
    assert kn.rate_hz == 1000.0
    np.testing.assert_allclose(kn.force_n, run.force_n[:, :3], rtol=1e-12)


def test_axis_mapping_and_signs_from_config():
    dyno = Dynamometer(
        model="test",
        channels=(
            DynoChannel(name="Fy", axis="x", sign=-1, sensitivity_pc_n=-7.9, range_n_v=500),
            DynoChannel(name="Fx", axis="y", sign=1, sensitivity_pc_n=-7.9, range_n_v=500),
            DynoChannel(name="Fz", axis="z", sign=-1, sensitivity_pc_n=-3.7, range_n_v=500),
        ),
    )
    run = import_run(DATA / "plain.csv", {"spindle_rpm": 600, "fz_mm": 0.2, "depth_mm": 1}, dyno)
    np.testing.assert_allclose(run.force_n[1], [20.25, 10.5, -3.125])


def test_bad_files(tmp_path):
    with pytest.raises(AnalysisError, match="mixed units"):
        import_run(DATA / "mixed_units.txt", {"spindle_rpm": 600, "fz_mm": 0.2, "depth_mm": 1})
    junk = tmp_path / "junk.txt"
    junk.write_text("hello\nworld\n")
    with pytest.raises(AnalysisError, match="no table of numbers"):
        read_force_table(junk)
    no_rate = tmp_path / "norate.csv"
    no_rate.write_text("Fx,Fy,Fz\n1,2,3\n1,2,3\n1,2,3\n1,2,3\n")
    with pytest.raises(AnalysisError, match="no sampling rate"):
        import_run(no_rate, {"spindle_rpm": 600, "fz_mm": 0.2, "depth_mm": 1})
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,Fx,Fy,Fz\n0,1,2,3\n0.001,1,2,3\n0.002,1,2,3\n0.003,1,x,3\n")
    with pytest.raises(AnalysisError, match=r"bad.csv:5: column Fy = 'x'"):
        read_force_table(bad)
    wrong = tmp_path / "wrong.csv"
    wrong.write_text("time_s,A,B,C\n0,1,2,3\n0.001,1,2,3\n0.002,1,2,3\n0.003,1,2,3\n")
    with pytest.raises(AnalysisError, match="cannot find the X, Y and Z"):
        import_run(wrong, {"spindle_rpm": 600, "fz_mm": 0.2, "depth_mm": 1})
    with pytest.raises(AnalysisError, match="not found"):
        read_force_table(tmp_path / "missing.txt")


def _write_dynoware(path: Path, run, header: dict) -> None:
    """A DynoWare-style export with decimal commas, as a German Windows writes it."""
    lines = ["DynoWare\tType 5697A", f"Sampling rate:\t{int(run.rate_hz)} Hz"]
    lines += [f"{k}:\t{str(v).replace('.', ',')}" for k, v in header.items()]
    lines += ["", "Zeit\tFx\tFy\tFz", "s\tN\tN\tN"]
    t = np.arange(len(run.force_n)) / run.rate_hz
    body = np.column_stack([t, run.force_n])
    lines += ["\t".join(f"{v:.6f}".replace(".", ",") for v in row) for row in body]
    path.write_text("\n".join(lines) + "\n", encoding="cp1252")


def test_identification_from_imported_dynoware_files(tmp_path):
    tool = FaceMill(kind="facemill", diameter_mm=125, inserts=1, lead_angle_deg=15,
                    axial_rake_deg=7, radial_rake_deg=0, nose_radius_mm=0.4)  # fmt: skip
    true = FaceMillCoefficients(K_T_n_mm2=405.4, K_R=1.1, P_T_n_mm=39.7, P_R_n_mm=19.6)
    rng = np.random.default_rng(2)
    runs = []
    for d in (0.5, 1.5, 3.0):
        c = RunConditions(spindle_rpm=600, fz_mm=0.236, depth_mm=d, width_mm=100.0)
        run = synthetic_facemill_run(f"d{d}", tool, true, c, 5000.0, cut_s=1.5, rng=rng,
                                     noise_frac=0.005, phase_rad=d)  # fmt: skip
        f = tmp_path / f"d{d}.txt"
        _write_dynoware(f, run, {"spindle_rpm": 600, "fz_mm": 0.236, "depth_mm": d,
                                 "width_mm": 100})  # fmt: skip
        runs.append(import_run(f))
    fit = fit_facemill_runs(runs, tool)
    assert fit.success, fit.message
    assert fit.coefficients.K_T_n_mm2 == pytest.approx(405.4, rel=0.02)
    assert fit.coefficients.P_T_n_mm == pytest.approx(39.7, rel=0.03)


def test_given_conditions_override_the_header_key_by_key(tmp_path):
    c = RunConditions(spindle_rpm=600, fz_mm=0.236, depth_mm=2.0, width_mm=100.0)
    tool = FaceMill(kind="facemill", diameter_mm=125, inserts=1, lead_angle_deg=15,
                    axial_rake_deg=7, radial_rake_deg=0, nose_radius_mm=0.4)  # fmt: skip
    true = FaceMillCoefficients(K_T_n_mm2=405.4, K_R=1.1, P_T_n_mm=39.7, P_R_n_mm=19.6)
    run = synthetic_facemill_run("r", tool, true, c, 5000.0, cut_s=0.2)
    f = tmp_path / "run.txt"
    _write_dynoware(f, run, {"fz_mm": 0.236, "depth_mm": 2, "width_mm": 100, "tool": "fm"})
    # The header's fz_mm, width and tool stay; depth_mm is replaced, spindle_rpm added.
    got = import_run(f, {"spindle_rpm": "600", "depth_mm": "1.5"}).conditions
    assert (got.fz_mm, got.depth_mm, got.spindle_rpm) == (0.236, 1.5, 600.0)
    assert got.width_mm == 100.0 and got.tool == "fm"
    # A feed per tooth given replaces a header's feed in mm/min.
    g = tmp_path / "feed.txt"
    _write_dynoware(g, run, {"feed_mm_min": 141.6, "teeth": 1, "depth_mm": 2})
    assert import_run(g, {"spindle_rpm": 600}).conditions.fz_mm == pytest.approx(0.236)
    assert import_run(g, {"spindle_rpm": 600, "fz_mm": 0.3}).conditions.fz_mm == 0.3
    # In neither: the error names the file and the key.
    with pytest.raises(AnalysisError, match=r"run\.txt.*missing condition 'spindle_rpm'"):
        import_run(f, {"depth_mm": 1.5})
    # A complete RunConditions replaces the header.
    assert import_run(f, c).conditions == c


def test_a_given_feed_replaces_the_recorded_one_in_either_form() -> None:
    from analysis.identify import merge_conditions

    rec = {"fz_mm": 0.1, "spindle_rpm": 600, "teeth": 2}
    assert merge_conditions(rec, {"feed_mm_min": 600}) == {
        "spindle_rpm": 600, "teeth": 2, "feed_mm_min": 600
    }  # fmt: skip
    rec = {"feed_mm_min": 600, "spindle_rpm": 600}
    assert merge_conditions(rec, {"fz_mm": 0.2}) == {"spindle_rpm": 600, "fz_mm": 0.2}
    assert merge_conditions(rec, {"depth_mm": 2}) == {**rec, "depth_mm": 2}
