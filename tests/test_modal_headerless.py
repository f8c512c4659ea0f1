"""A tap test as many labs' loggers record it: no header row, columns time (s), hammer (N),
acceleration (m/s^2) at 51.2 kHz, one hit. The record is made here by scipy's own simulation of
one mode (m x'' + c x' + k x = F, independent of cutlab's filters), so the expected modal
figures are the ones put in."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy import signal

from rig.cli import main

FS = 51_200.0
F_HZ, ZETA, K_N_M = 900.0, 0.03, 2.0e7


def _tap_file(path, hits=(0.01,), sep=",", seed=0) -> None:
    rng = np.random.default_rng(seed)
    n = int(FS * 0.2)
    t = np.arange(n) / FS
    ham = np.zeros(n)
    for t0 in hits:
        m = (t >= t0) & (t < t0 + 0.0002)
        ham[m] = 150 * np.sin(np.pi * (t[m] - t0) / 0.0002)
    wn = 2 * math.pi * F_HZ
    mass = K_N_M / wn**2
    # acceleration per force of one mode: s^2 / (m s^2 + c s + k)
    sys_ = signal.TransferFunction([1.0, 0, 0], [mass, 2 * ZETA * wn * mass, K_N_M])
    _, acc, _ = signal.lsim(sys_, ham, t)
    acc = acc + rng.normal(0, 0.002 * np.abs(acc).max(), n)
    ham = ham + rng.normal(0, 0.05, n)
    rows = np.column_stack([t, ham, acc])
    path.write_text("\n".join(sep.join(f"{v:.9g}" for v in r) for r in rows) + "\n")


def _modal(argv, capsys):
    code = main(["analyze", "modal", *argv])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.parametrize("sep", [",", "\t", " "])
def test_headerless_single_hit_with_columns(tmp_path, capsys, sep) -> None:
    f = tmp_path / "tap.txt"
    _tap_file(f, sep=sep)
    code, out, err = _modal(
        [str(f), "--columns", "time[s],hammer[N],accel[m/s^2]", "--json"], capsys
    )
    assert code == 0, err
    got = json.loads(out)
    (mode,) = got["modes"]
    assert mode["frequency_hz"] == pytest.approx(F_HZ, rel=0.01)
    assert mode["damping_ratio"] == pytest.approx(ZETA, rel=0.15)
    assert mode["stiffness_n_m"] == pytest.approx(K_N_M, rel=0.15)
    assert mode["coherence"] is None and "one hit" in mode["coherence_reason"]
    assert mode["frequency_hz_uncertainty"] > 0 and mode["damping_ratio_uncertainty"] >= 0
    assert got["hits_used"] == [0]
    assert any(w.startswith("one hit: no coherence") for w in got["warnings"])


def test_three_hits_keep_coherence(tmp_path, capsys) -> None:
    f = tmp_path / "tap.csv"
    _tap_file(f, hits=(0.01, 0.07, 0.13))
    code, out, err = _modal(
        [str(f), "--columns", "time[s],hammer[N],accel[m/s^2]", "--record-s", "0.05", "--json"],
        capsys,
    )
    assert code == 0, err
    (mode,) = json.loads(out)["modes"]
    assert mode["coherence"] > 0.9
    assert mode["frequency_hz"] == pytest.approx(F_HZ, rel=0.01)


@pytest.mark.faults
@pytest.mark.parametrize(
    "columns,words",
    [
        (None, ["no header row", "--columns"]),
        ("time[s],hammer[N]", ["3 data columns", "--columns names 2"]),
        ("time[h],hammer[N],accel[m/s^2]", ["time unit"]),
        ("time[s],hammer[N],hammer[N]", ["appears twice"]),
        ("time[s],hammer[N],accel[furlong]", ["unit 'furlong'"]),
    ],
)
def test_headerless_bad_input_is_one_line(tmp_path, capsys, columns, words) -> None:
    f = tmp_path / "tap.csv"
    _tap_file(f)
    argv = [str(f)] + (["--columns", columns] if columns else []) + ["--response", "accel"]
    code, _, err = _modal(argv, capsys)
    assert code == 2
    line = err.strip()
    assert line.startswith("cutlab: error: ") and "\n" not in line and "Traceback" not in line
    for w in words:
        assert w in line, line
