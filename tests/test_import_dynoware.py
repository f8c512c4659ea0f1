"""Importing DynoWare exports as labs make them: header styles, channel names, decimal commas,
exports holding only the steady cut, axis mappings (and the check that catches a wrong one),
conditions tables and a user's own tool catalogue.

The exports come from tests/_dynoware_files.py, which computes slot forces from Altintas' model on
its own, so the fitted coefficients are checked against known ones.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from _dynoware_files import (
    AP_MM,
    DIAMETER_MM,
    RATE_HZ,
    RPM,
    TEETH,
    TOOL,
    TOOLS_TOML,
    TRUTH,
    conditions_csv,
    slot_record,
    to_columns,
    write_export,
    write_slot_exports,
)

from analysis.config import Dynamometer, DynoChannel
from analysis.errors import AnalysisError, ConfigError
from analysis.identify import (
    ImportOptions,
    find_tool,
    fit_files,
    load_conditions_table,
    load_export,
    parse_axes,
    read_force_table,
)
from analysis.identify.importers import NO_AIR_ZEROED

TRUE_AXES = "x=-Fy,y=Fx,z=-Fz"  # how the lab's dynamometer sits relative to the feed


def _coefs(out: dict) -> dict[str, float]:
    return {k: out["coefficients"][k] for k in TRUTH}


def _assert_truth(got: dict[str, float], rel: float = 0.01) -> None:
    for k, v in TRUTH.items():
        # Kae is small (1.8 N/mm): judged against the edge coefficients' scale.
        tol = 0.3 if k == "Kae" else rel * v
        assert got[k] == pytest.approx(v, abs=tol), (k, got)


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """The lab's slot exports (air before and after, amplifier offset, DynoWare header with the
    conditions, decimal comma), a steady-only set without header, and the lab's tool file."""
    d = tmp_path_factory.mktemp("lab")
    tools = d / "my_tools.toml"
    tools.write_text(TOOLS_TOML)
    with_air = write_slot_exports(d, TRUE_AXES, decimal=",", cut_s=0.6)
    steady = d / "steady"
    steady.mkdir()
    trimmed = write_slot_exports(steady, TRUE_AXES, header=False, air_s=0.0, cut_s=0.6,
                                 offset_n=(0.0, 0.0, 0.0), sep=";", decimal=",")  # fmt: skip
    return {"dir": d, "tools": tools, "air": with_air, "steady": trimmed}


def test_header_styles_and_channel_names(tmp_path):
    t, f = slot_record(600.0, cut_s=0.1, air_s=0.05)
    cols = {"Kraft X [N]": f[:, 0], "Kraft Y [N]": f[:, 1], "Kraft Z [N]": f[:, 2]}
    cases = [
        (":,", ",", "."),  # DynoWare CSV: "fz_mm:,0.05"
        (":\t", "\t", ","),
        (";", ";", ","),
        (": ", "\t", "."),
    ]
    for k, (hsep, sep, dec) in enumerate(cases):
        p = write_export(tmp_path / f"e{k}.csv", t, cols, {"fz_mm": 0.05, "ap_mm": 3.0,
                         "spindle_rpm": 6000.0}, sep=sep, decimal=dec, header_sep=hsep,
                         units=False)  # fmt: skip
        table = read_force_table(p)
        assert table.header["fz_mm"].replace(",", ".") == "0.05", (hsep, table.header)
        assert table.rate_hz == RATE_HZ
        ex = load_export(p)  # 'Kraft X' is found as x without a mapping
        assert ex.axes == "x=Kraft X,y=Kraft Y,z=Kraft Z"
        assert ex.run.conditions.fz_mm == 0.05 and ex.run.conditions.depth_mm == 3.0
        np.testing.assert_allclose(ex.run.force_n, f, atol=1e-5)
    # Channels with neutral names need the mapping; the unit suffix and case do not matter.
    neutral = {"Channel 1 [N]": f[:, 1], "Channel 2 [N]": -f[:, 0], "Channel 3 [N]": f[:, 2]}
    p = write_export(tmp_path / "ch.txt", t, neutral, {"fz_mm": 0.05, "ap_mm": 3.0,
                     "spindle_rpm": 6000.0})  # fmt: skip
    with pytest.raises(AnalysisError, match="cannot find the X, Y and Z.*--axes"):
        load_export(p)
    ex = load_export(p, axes="x=-channel 2,y=CHANNEL 1,z=Channel 3 [N]")
    np.testing.assert_allclose(ex.run.force_n, f, atol=1e-5)
    with pytest.raises(AnalysisError, match=r"y = 'Fy' is not a column \(columns: Time, Ch"):
        load_export(p, axes="x=Channel 1,y=Fy,z=Channel 3")


@pytest.mark.parametrize(
    ("text", "why"),
    [("x=Fx,y=Fy", "no column for z"), ("x=Fx,x=Fy,z=Fz", "x given twice"),
     ("x:Fx,y=Fy,z=Fz", "is not AXIS=COLUMN")],
)  # fmt: skip
def test_bad_axes_are_one_clear_line(text, why):
    with pytest.raises(AnalysisError, match=why) as e:
        parse_axes(text)
    assert "\n" not in str(e.value)


@pytest.mark.long
def test_exports_with_air_recover_the_coefficients(lab):
    opts = ImportOptions(axes=TRUE_AXES, tools_path=lab["tools"])
    out = fit_files(lab["air"], "endmill", TOOL, options=opts)
    assert out["success"], out["message"]
    _assert_truth(_coefs(out))
    assert out["axes"] == TRUE_AXES and out["warnings"] == []
    assert {r["zero"] for r in out["per_run"]} == {"air"}
    assert out["coefficient_units"]["Ktc"] == "N/mm^2" and out["coefficient_units"]["Kae"] == "N/mm"


@pytest.mark.long
def test_steady_only_export_is_taken_as_zeroed_and_says_so(lab):
    ex = load_export(lab["steady"][0], axes=TRUE_AXES, layers=[("row", {
        "spindle_rpm": RPM, "feed_mm_min": 300, "ap_mm": AP_MM, "ae_mm": DIAMETER_MM,
        "teeth": TEETH, "mode": "slot"})])  # fmt: skip
    assert ex.zero == NO_AIR_ZEROED
    table = conditions_csv(lab["dir"] / "steady.csv", lab["steady"], sep=";")
    opts = ImportOptions(axes=TRUE_AXES, table=table, tools_path=lab["tools"])
    out = fit_files(lab["steady"], "endmill", TOOL, options=opts)
    assert out["success"], out["message"]
    _assert_truth(_coefs(out))
    assert len(out["warnings"]) == 4 and all(NO_AIR_ZEROED in w for w in out["warnings"])


def test_wrong_axes_warn_with_the_figures(lab):
    opts = ImportOptions(tools_path=lab["tools"])  # default: x=Fx, y=Fy, z=Fz
    with pytest.raises(AnalysisError) as exc:  # Krc < 0 cannot be a coefficient set: refused
        fit_files(lab["air"], "endmill", TOOL, options=opts)
    w = str(exc.value)
    assert "x=Fx,y=Fy,z=Fz give a negative cutting coefficient (Krc" in w
    assert "cannot tell them apart" in w and "give --axes" in w
    # x and y swapped with a sign: a slot fits it as well, with Ktc and Krc traded.
    opts = ImportOptions(axes="x=-Fx,y=Fy,z=-Fz", tools_path=lab["tools"])
    out = fit_files(lab["air"], "endmill", TOOL, options=opts)
    assert out["success"] and out["coefficients"]["Krc"] == pytest.approx(796, rel=0.01)
    (w,) = out["warnings"]
    assert "give Krc > Ktc" in w and "Ktc 168" in w and "check --axes" in w
    # Every candidate's figures are in the result.
    cands = {c["axes"]: c for c in out["axes_check"]}
    assert len(cands) == 48 and cands[TRUE_AXES]["coefficients"]["Ktc"] == pytest.approx(796, 0.01)


def test_rig_config_mapping_with_signed_axes(lab):
    ch = [DynoChannel(name=n, axis=a, sensitivity_pc_n=-7.9, range_n_v=500)
          for n, a in (("Fy", "-x"), ("Fx", "y"), ("Fz", "-z"))]  # fmt: skip
    assert (ch[0].axis, ch[0].sign) == ("x", -1)
    teeth = {"teeth": TEETH}  # the header gives feed_mm_min
    ex = load_export(lab["air"][0], teeth, Dynamometer(model="9257B", channels=ch))
    assert ex.axes == TRUE_AXES
    by_string = Dynamometer(model="9257B", channels=ch[:1], axes="x=-Fy, y=Fx, z=-Fz")
    assert load_export(lab["air"][0], teeth, by_string).axes == TRUE_AXES


def test_zero_from_a_zero_file_a_header_or_zeroed(tmp_path):
    t, f = slot_record(600.0, cut_s=0.3, air_s=0.0, offset_n=(5.0, -7.0, 3.0), noise_n=0.0)
    cols = to_columns(f, "x=Fx,y=Fy,z=Fz")
    hdr = {"spindle_rpm": RPM, "fz_mm": 0.05, "ap_mm": AP_MM, "mode": "slot"}
    p = write_export(tmp_path / "cut.txt", t, cols, hdr)
    rest = write_export(tmp_path / "rest.txt", t[:500], {"Fx": np.full(500, 5.0),
                        "Fy": np.full(500, -7.0), "Fz": np.full(500, 3.0)}, {})  # fmt: skip
    ex = load_export(p, zero_file=rest)
    assert ex.zero.startswith("zero file rest.txt (5, -7, 3 N)")
    np.testing.assert_allclose(ex.run.force_n, f - [5.0, -7.0, 3.0], atol=1e-5)
    q = write_export(tmp_path / "cut2.txt", t, cols, {**hdr, "Offset Fx": 5.0,
                     "Offset Fy": -7.0, "Offset Fz": 3.0})  # fmt: skip
    ex = load_export(q)
    assert ex.zero.startswith("header offsets")
    np.testing.assert_allclose(ex.run.force_n, f - [5.0, -7.0, 3.0], atol=1e-5)
    ex = load_export(p, zeroed=True)
    assert ex.zero.startswith("--zeroed") and np.allclose(ex.run.force_n, f, atol=1e-5)


def test_conditions_table_csv_and_toml(lab, tmp_path):
    files = lab["air"]
    t = load_conditions_table(conditions_csv(tmp_path / "c.csv", files))
    where, row = t.row(files[1])
    assert where.endswith("c.csv:3")
    assert row == {"spindle_rpm": 6000, "feed_mm_min": 600, "depth_mm": 3, "width_mm": 25,
                   "teeth": 2, "tool": TOOL}  # fmt: skip
    toml = tmp_path / "c.toml"
    toml.write_text('[[runs]]\nfile = "cut_300.txt"\nspindle_rpm = 6000\nfz_mm = 0.025\n'
                    'ap_mm = 3\nae_mm = 25\nmode = "slot"\n')  # fmt: skip
    ex = load_export(files[0], axes=TRUE_AXES, layers=[load_conditions_table(toml).row(files[0])])
    assert ex.run.conditions.fz_mm == 0.025 and ex.run.conditions.width_mm == 25


@pytest.mark.parametrize(
    ("table", "expect"),
    [
        ("file,spindle_rpm,feed_mm_min,ap_mm,ae_mm,depth\ncut_300,6000,300,3,25,3\n",
         r"c\.csv:2: unknown condition 'depth' = '3'"),
        ("file,spindle_rpm,feed_mm_min,ap_mm,ae_mm,teeth\ncut_300,6000,300,3,25,4\n",
         r"c\.csv:2: teeth = 4 but tool 'lab-phi25-2f' has 2 teeth"),
        ("file,spindle_rpm,feed_mm_min,ap_mm,ae_mm\ncut_999,6000,300,3,25\n",
         r"c\.csv: no row for cut_300\.txt \(field file"),
        ("file,spindle_rpm,feed_in_min,ap_mm,ae_mm\ncut_300,6000,12,3,25\n",
         r"c\.csv:2: feed_in_min = '12': .*mixed units"),
        ("file,spindle_rpm,fz_mm,feed_mm_min,ap_mm,ae_mm\ncut_300,6000,0.1,300,3,25\n",
         r"c\.csv:2: fz_mm = 0\.1 contradicts feed_mm_min = 300"),
        ("file,spindle_rpm,feed_mm_min,ap_mm,depth_mm,ae_mm\ncut_300,6000,300,3,2,25\n",
         r"c\.csv:2: depth_mm = '2' contradicts depth_mm = 3"),
    ],
)  # fmt: skip
def test_bad_conditions_tables_name_file_and_field(lab, tmp_path, table, expect):
    p = tmp_path / "c.csv"
    p.write_text(table)
    opts = ImportOptions(axes=TRUE_AXES, table=p, tools_path=lab["tools"])
    with pytest.raises(AnalysisError, match=expect) as e:
        fit_files(lab["air"][:1], "endmill", TOOL, options=opts)
    assert "\n" not in str(e.value)


def test_unknown_header_condition_and_pattern(tmp_path):
    t, f = slot_record(600.0, cut_s=0.1, air_s=0.05)
    cols = to_columns(f, "x=Fx,y=Fy,z=Fz")
    p = write_export(tmp_path / "cut_6000rpm_f600.txt", t, cols, {"ap_mm": 3.0, "ae_mm": 25.0,
                     "Comment": "slot test", "stepover_mm": 1.0})  # fmt: skip
    with pytest.raises(AnalysisError, match=r"\(header\): unknown condition 'stepover_mm'"):
        load_export(p)
    q = write_export(tmp_path / "cut_6000rpm_f600b.txt", t, cols, {"ap_mm": 3.0, "ae_mm": 25.0,
                     "Comment": "slot test"})  # fmt: skip
    opts = ImportOptions(pattern="cut_{spindle_rpm}rpm_f{feed_mm_min}b.txt").loaded()
    ex = load_export(q, layers=opts.layers(q), teeth_of=lambda name: TEETH, expected_tool=TOOL)
    assert ex.run.conditions.spindle_rpm == 6000 and ex.run.conditions.fz_mm == 0.05


def test_user_tool_catalogue_beside_the_data(lab):
    tool = find_tool(TOOL, lab["tools"])
    assert tool.flutes == 2 and tool.diameter_mm == 25
    assert find_tool("phi10-flat", lab["tools"]).diameter_mm == 10  # shipped ones still there
    with pytest.raises(ConfigError, match=r"my_tools\.toml: tool 'nope' not found"):
        find_tool("nope", lab["tools"])
    with pytest.raises(ConfigError, match="tool 'lab-phi25-2f' not found"):
        find_tool(TOOL)  # the install's catalogue was not edited
    assert Path(lab["tools"]).read_text() == TOOLS_TOML


def test_mixed_immersions_show_a_wrong_mapping_by_its_residual(tmp_path):
    """Slots alone cannot tell x=-Fx,y=Fy from the true mapping; with down-milling runs beside
    them the wrong one leaves a residual of tens of N, and the warning gives both fits."""
    tools = tmp_path / "t.toml"
    tools.write_text(TOOLS_TOML)
    (tmp_path / "slot").mkdir()
    (tmp_path / "down").mkdir()
    files = write_slot_exports(tmp_path / "slot", TRUE_AXES, feeds=(300.0, 1500.0), cut_s=0.5)
    files += write_slot_exports(tmp_path / "down", TRUE_AXES, feeds=(600.0, 1000.0), cut_s=0.5,
                                ae_mm=DIAMETER_MM / 4)  # fmt: skip
    out = fit_files(files, "endmill", TOOL, options=ImportOptions(TRUE_AXES, tools_path=tools))
    assert out["success"] and out["warnings"] == []
    _assert_truth(_coefs(out))
    wrong = "x=-Fx,y=Fy,z=-Fz"
    with pytest.raises(AnalysisError) as exc:  # refused (issue 27), with both fits
        fit_files(files, "endmill", TOOL, options=ImportOptions(wrong, tools_path=tools))
    w = str(exc.value)
    assert f"axes {wrong} fit clearly worse than another mapping" in w
    assert f"the runs fit {TRUE_AXES}: Ktc 796" in w and "R^2 1.00000" in w
