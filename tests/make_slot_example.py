"""Writes the end-mill example of README "analyze forces" into data/slots/: slot cuts of the
phi10-flat end mill (configs/tools.toml: 10 mm, 3 flutes, 30 deg helix) at 3000 rpm, 2 mm deep,
one plain CSV export per feed per tooth, each with its feed as a ``fz_mm: ...`` header line (the
way a lab names the condition that differs from cut to cut), plus truth.json (the coefficients the
exports were made with). 0.1 mm is above the tool's 0.08 mm largest chip: the fit names it and
leaves it out.

The forces come from tests/_force_sim.py, a time-domain simulation written apart from cutlab's
fitting code (helical edge, runout, spindle-speed wobble, the dynamometer's modes, noise).

    .venv/bin/python tests/make_slot_example.py     # rewrites data/slots/
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _dynoware_files import write_export  # noqa: E402
from _force_sim import LINEAR, Cut, Law, Record, simulate  # noqa: E402

OUT = Path(__file__).resolve().parent.parent / "data" / "slots"
TRUTH = dict(zip(LINEAR, (800.0, 240.0, 140.0, 22.0, 30.0, 3.0)))  # an Al 6061-T6-like law
RPM, DEPTH_MM, RATE_HZ = 3000.0, 2.0, 10_000.0
FZ_MM = (0.03, 0.04, 0.05, 0.07, 0.1)


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    for k, fz in enumerate(FZ_MM):
        cut = Cut(diameter_mm=10.0, flutes=3, helix_deg=30.0, spindle_rpm=RPM, fz_mm=fz,
                  depth_mm=DEPTH_MM, runout_mm=(0.001, 0.0, -0.001))  # fmt: skip
        rec = Record(rate_hz=RATE_HZ, air_revs=0, ramp_revs=0, steady_revs=30, rpm_wobble=0.005,
                     noise_n=2.0, modes=((2900.0, 0.03), (3300.0, 0.03), (4100.0, 0.03)),
                     seed=200 + k)  # fmt: skip
        t, f = simulate(cut, Law("linear", TRUTH), rec)
        columns = {"Fx": f[:, 0], "Fy": f[:, 1], "Fz": f[:, 2]}
        write_export(OUT / f"slot_{fz:g}.csv", t, columns, {"fz_mm": fz}, sep=",",
                     header_sep=": ")  # fmt: skip
    truth = {k.split("_")[0]: v for k, v in TRUTH.items()}
    (OUT / "truth.json").write_text(
        json.dumps(
            {"coefficients": truth, "tool": "phi10-flat", "units": "N/mm^2 (K?c), N/mm (K?e)"},
            indent=1,
        )
    )
    print(f"wrote {len(FZ_MM)} exports and truth.json to {OUT}")


if __name__ == "__main__":
    np.seterr(all="raise")
    main()
