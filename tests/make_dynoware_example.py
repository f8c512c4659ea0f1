"""Writes the worked example of README "I have DynoWare exports of test cuts" into
data/dynoware/: five slot-milling exports as a German Windows DynoWare writes them (tab separated,
decimal comma, a header block, Time and Fx Fy Fz columns, the air trimmed by the operator, the
dynamometer mounted turned by 90 degrees so the mapping is x=-Fy,y=Fx,z=-Fz), the conditions
table and the lab's own tool catalogue, plus truth.json (the coefficients the exports were made
with).

The forces come from tests/_force_sim.py, a time-domain simulation written apart from cutlab's
fitting code (helical edge, runout, spindle-speed wobble, the dynamometer's modes, noise).

    .venv/bin/python tests/make_dynoware_example.py     # rewrites data/dynoware/
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _dynoware_files import to_columns, write_export  # noqa: E402
from _force_sim import LINEAR, Cut, Law, Record, simulate  # noqa: E402

OUT = Path(__file__).resolve().parent.parent / "data" / "dynoware"
TRUTH = dict(zip(LINEAR, (720.0, 215.0, 130.0, 24.0, 31.0, 2.5)))  # Al 7075-T6-like
RPM, TEETH, DIAMETER_MM, AP_MM, RATE_HZ = 6000.0, 2, 25.0, 3.0, 10_000.0
FEEDS_MM_MIN = (300, 600, 900, 1200, 1500)
AXES = "x=-Fy,y=Fx,z=-Fz"
TOOLS = """\
# The lab's own cutters (kept next to the data; cutlab's configs/tools.toml stays untouched).
[tools.lab-phi25-2f]
kind = "flat"
description = "25 mm two-flute carbide end mill, 30 deg helix"
diameter_mm = 25.0
flute_length_mm = 40.0
flutes = 2
helix_deg = 30.0
"""


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    rows = ["file,spindle_rpm,feed_mm_min,ap_mm,ae_mm,teeth,tool"]
    for k, feed in enumerate(FEEDS_MM_MIN):
        cut = Cut(diameter_mm=DIAMETER_MM, flutes=TEETH, helix_deg=30.0, spindle_rpm=RPM,
                  fz_mm=feed / (RPM * TEETH), depth_mm=AP_MM,
                  runout_mm=(0.001, -0.001))  # fmt: skip
        rec = Record(rate_hz=RATE_HZ, air_revs=0, ramp_revs=0, steady_revs=60, rpm_wobble=0.005,
                     noise_n=3.0, modes=((2900.0, 0.03), (3300.0, 0.03), (4100.0, 0.03)),
                     seed=100 + k)  # fmt: skip
        t, f = simulate(cut, Law("linear", TRUTH), rec)
        header = {"Measurement": f"slot {k + 1} Al7075 phi25", "Date": "12.03.2026",
                  "Number of samples": len(t), "Comment": f"f = {feed} mm/min"}  # fmt: skip
        write_export(OUT / f"cut_{feed}.txt", t, to_columns(f, AXES), header, sep="\t",
                     decimal=",")  # fmt: skip
        rows.append(f"cut_{feed},{RPM:g},{feed},{AP_MM:g},{DIAMETER_MM:g},{TEETH},lab-phi25-2f")
    (OUT / "conditions.csv").write_text("\n".join(rows) + "\n")
    (OUT / "my_tools.toml").write_text(TOOLS)
    truth = {k.split("_")[0]: v for k, v in TRUTH.items()}
    (OUT / "truth.json").write_text(json.dumps({"coefficients": truth, "axes": AXES,
                                                "units": "N/mm^2 (K?c), N/mm (K?e)"}, indent=1))
    print(f"wrote {len(FEEDS_MM_MIN)} exports, conditions.csv, my_tools.toml, truth.json to {OUT}")


if __name__ == "__main__":
    np.seterr(all="raise")
    main()
