"""Several modes per channel from tap tests: stabilisation diagram, LSFD modal mass and stiffness,
the saved modes file.

The records come from this file's own generator: each channel is a sum of modes whose response to
a half-sine hammer pulse is written in closed form (the convolution of the pulse with the damped
sinusoid h_r(t) = exp(-zeta w t) sin(w_d t) / (m_r w_d) integrated analytically), plus noise.
"""

from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

FS = 51_200.0
PULSE_S = 0.00015  # a steel tip: flat hammer spectrum to ~6 kHz
HITS_S = (0.02, 0.12, 0.22, 0.32, 0.42)


def _pulse_response(t, t0, amp_n, modes, kind):
    """Closed-form response of ``modes`` [(f_hz, zeta, k_n_m), ...] to a half-sine pulse of
    ``amp_n`` starting at ``t0``: displacement (m) or acceleration (m/s^2)."""
    a = math.pi / PULSE_S
    tau = t - t0
    on = tau >= 0
    u = np.clip(tau, 0.0, PULSE_S)
    out = np.zeros_like(t)
    for f_hz, zeta, k in modes:
        wn = 2 * math.pi * f_hz
        wd = wn * math.sqrt(1 - zeta * zeta)
        m = k / wn**2
        p = complex(-zeta * wn, wd)
        # int_0^u sin(a s) exp(p (tau - s)) ds, sin = (e^{ias} - e^{-ias}) / 2i
        e = np.exp(p * np.where(on, tau, 0.0))
        i1 = (np.exp((1j * a - p) * u) - 1) / (1j * a - p)
        i2 = (np.exp((-1j * a - p) * u) - 1) / (-1j * a - p)
        conv = e * (i1 - i2) / 2j
        if kind == "disp":
            out += np.where(on, amp_n * np.imag(conv) / (m * wd), 0.0)
        elif kind == "accel":  # x'' = f * h'' + f(t) h'(0), h'(0) = 1 / m
            force = np.where(on & (tau < PULSE_S), amp_n * np.sin(a * u), 0.0)
            out += np.where(on, amp_n * np.imag(p * p * conv) / (m * wd), 0.0) + force / m
        else:
            raise ValueError(kind)
    return out


def tap_record(channels, kind="disp", noise=1e-3, seed=0, hits=HITS_S, seconds=0.55):
    """Hammer force (N) and responses (n, c): ``channels`` one list of modes per channel (an
    empty list is a channel with noise only). ``noise``: the response noise's standard deviation
    as a fraction of the response's peak (of the largest channel)."""
    rng = np.random.default_rng(seed)
    n = int(FS * seconds)
    t = np.arange(n) / FS
    ham = np.zeros(n)
    resp = np.zeros((n, len(channels)))
    for t0 in hits:
        t0 += rng.uniform(0, 0.001)
        amp = rng.uniform(80, 120)
        on = (t >= t0) & (t < t0 + PULSE_S)
        ham[on] += amp * np.sin(math.pi * (t[on] - t0) / PULSE_S)
        for c, modes in enumerate(channels):
            resp[:, c] += _pulse_response(t, t0, amp, modes, kind)
    sd = noise * np.abs(resp).max()
    resp += rng.normal(0, sd, resp.shape)
    return t, ham + rng.normal(0, 0.05, n), resp


def _analyse(channels, kind="disp", seed=0, noise=1e-3, response=None):
    """Generate ``kind`` (disp or accel) and analyse it as ``response`` (default: ``kind``)."""
    from analysis.modal import ImpactRecord, modal_analysis

    _, ham, resp = tap_record(channels, kind, noise=noise, seed=seed)
    names = tuple("xyz"[: len(channels)])
    return modal_analysis(ImpactRecord(ham, resp, FS, names, "tap", response or kind))


def _check(found, truth, stiffness=True):
    """Each true mode (f_hz, zeta, k) matched by one found mode: 1 % in frequency, 15 % in
    damping, 10 % in modal stiffness (and mass = k / w^2)."""
    assert len(found) == len(truth), [m.frequency_hz for m in found]
    for m, (f, z, k) in zip(found, truth):
        assert m.frequency_hz == pytest.approx(f, rel=0.01)
        assert m.damping_ratio == pytest.approx(z, rel=0.15)
        if stiffness:
            assert m.stiffness_n_m == pytest.approx(k, rel=0.10)
            assert m.mass_kg == pytest.approx(k / (2 * math.pi * f) ** 2, rel=0.10)
            c = 2 * z * math.sqrt(k * k / (2 * math.pi * f) ** 2)
            assert m.damping_n_s_m == pytest.approx(c, rel=0.2)


TWO = [(1810.0, 0.03, 2.0e7), (2600.0, 0.04, 3.0e7)]


@pytest.mark.parametrize(("kind", "noise"), [("disp", 1e-2), ("accel", 1e-3)])
def test_1810_and_2600_hz_both_found_with_their_stiffness(kind, noise):
    res = _analyse([TWO], kind, noise=noise)
    _check(res.modes, TWO)
    assert all(m.response == kind and m.coherence > 0.95 for m in res.modes)


def test_three_modes_and_closely_spaced_modes():
    three = [(900.0, 0.05, 5.0e7), *TWO]
    close = [(2000.0, 0.02, 2.0e7), (2100.0, 0.02, 4.0e7)]  # 5 % apart, peaks overlap
    res = _analyse([three, close], "disp", seed=2)
    _check([m for m in res.modes if m.channel == "x"], three)
    _check([m for m in res.modes if m.channel == "y"], close)


def test_noise_only_channel_gives_no_mode_and_says_why():
    res = _analyse([TWO, []], "accel", seed=3)
    assert {m.channel for m in res.modes} == {"x"}
    ((name, why),) = res.skipped
    assert name == "y" and why.startswith("no mode: coherence")


def test_force_response_keeps_the_dynamometer_meaning():
    # A one-mode force/force FRF of unit static gain: with k = 1 the generator's displacement is
    # numerically that force. Frequency and damping as before, no modal mass, gain share 1.
    res = _analyse([[(2050.0, 0.02742, 1.0)]], "disp", seed=4, response="force")
    (m,) = res.modes
    assert m.frequency_hz == pytest.approx(2050.0, rel=0.01)
    assert m.damping_ratio == pytest.approx(0.02742, rel=0.15)
    assert math.isnan(m.stiffness_n_m) and math.isnan(m.mass_kg)
    assert m.residue / (2 * math.pi * m.frequency_hz) ** 2 == pytest.approx(1.0, rel=0.10)


def test_stabilisation_diagram_marks_stable_poles_at_the_modes():
    res = _analyse([TWO], "disp", seed=5)
    st = res.stabilisation["x"]
    assert list(st.orders[:3]) == [2, 4, 6]
    counted = np.concatenate([f[s == 4] for f, s in zip(st.freq_hz, st.state)])
    for f, _, _ in TWO:  # every counted pole sits on a true mode (windowed frequency)
        assert np.any(np.abs(counted - f) < 0.01 * f)
    assert np.all(np.min(np.abs(counted[:, None] - [1810.0, 2600.0]), axis=1) < 0.02 * 2600)


@pytest.mark.timeout(60)
def test_record_s_too_small_is_refused_not_a_hang(tmp_path, capsys):
    from rig.cli import main

    path = _write_csv(tmp_path / "tap.csv", [TWO], "disp", "dx [m]")
    for bad in ("0.0005", "5"):  # a positive number, refused against the record
        rc = main(["analyze", "modal", str(path), "--record-s", bad])
        err = capsys.readouterr().err
        assert rc == 2, bad
        assert err.count("\n") == 1 and "--record-s" in err and f"= {float(bad):g} s" in err
        assert "expected 0.01 to" in err
    for bad in ("0", "-1"):  # not a positive number: refused when the options are parsed
        with pytest.raises(SystemExit) as exc:
            main(["analyze", "modal", str(path), "--record-s", bad])
        err = capsys.readouterr().err
        assert exc.value.code == 2 and err.count("\n") == 1 and "--record-s" in err


def test_too_many_hits_are_refused():
    from analysis.errors import AnalysisError
    from analysis.modal.hammer import MAX_HITS, split_hits

    rate = 12_800.0  # 128 samples = 0.01 s, the shortest record
    ham = np.zeros(150 * (MAX_HITS + 5))
    ham[::150] = 100.0
    with pytest.raises(AnalysisError, match=f"more than {MAX_HITS} hits"):
        split_hits(ham, rate, 0.01)


def _write_csv(path, channels, kind, *columns, seed=0):
    t, ham, resp = tap_record(channels, kind, seed=seed)
    header = ",".join(["time_s", "hammer [N]", *columns])
    np.savetxt(path, np.column_stack([t, ham, resp]), delimiter=",", fmt="%.10g", header=header,
               comments="")  # fmt: skip
    return path


def test_units_in_column_names_decide_the_response(tmp_path):
    from analysis.errors import AnalysisError
    from analysis.modal import hammer_file_record

    t, ham, resp = tap_record([TWO, TWO], "accel", seed=6)
    path = tmp_path / "tap.csv"
    data = np.column_stack([t, ham, resp[:, 0] / 9.80665, resp[:, 1] * 1.0])
    np.savetxt(path, data, delimiter=",", fmt="%.10g", comments="",
               header="time_s,hammer [N],ax [g],ay [m/s^2]")  # fmt: skip
    rec = hammer_file_record(path)
    assert rec.channels == ("x", "y") and rec.responses == ("accel", "accel")
    np.testing.assert_allclose(rec.response[:, 0], resp[:, 0], rtol=1e-8, atol=1e-12)
    with pytest.raises(AnalysisError, match=r"column ax is in g \(accel\) but --response is disp"):
        hammer_file_record(path, response="disp")


def test_cli_writes_stabilisation_png_and_modes_that_load_back(tmp_path, capsys):
    from analysis.modal import load_modes
    from rig.cli import main

    # No units in the column names: --response says the channel is an acceleration.
    path = _write_csv(tmp_path / "tap.csv", [TWO, []], "accel", "ax", "ay", seed=7)
    png, saved = tmp_path / "stab.png", tmp_path / "tool.toml"
    rc = main(["analyze", "modal", str(path), "--response", "accel", "--stabilisation",
               str(png), "--save", str(saved), "--json"])  # fmt: skip
    out = json.loads(capsys.readouterr().out)
    assert rc == 0
    assert png.stat().st_size > 10_000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = out["modes"]
    assert [r["axis"] for r in rows] == ["x", "x"]
    for r, (f, _, k) in zip(rows, TWO):
        assert r["frequency_hz"] == pytest.approx(f, rel=0.01)
        assert r["stiffness_n_m"] == pytest.approx(k, rel=0.10)
    modes = load_modes(saved)
    assert set(modes.directions) == {"x"} and modes.source == "tap.csv"
    for m, r in zip(modes.modes("x"), rows):
        assert m.frequency_hz == pytest.approx(r["frequency_hz"], rel=1e-12)
        assert m.damping_ratio == pytest.approx(r["damping_ratio"], rel=1e-12)
        assert m.stiffness_n_m == pytest.approx(r["stiffness_n_m"], rel=1e-12)
        assert m.mass_kg == pytest.approx(r["mass_kg"], rel=1e-12)


def test_save_and_load_round_trip_and_receptance(tmp_path):
    from analysis.modal import ModalMode, load_modes, save_modes

    def mode(ch, f, z, k):
        m = k / (2 * math.pi * f) ** 2
        return SimpleNamespace(channel=ch, frequency_hz=f, damping_ratio=z, stiffness_n_m=k,
                               mass_kg=m)  # fmt: skip

    given = [mode("x", 2600.0, 0.04, 3e7), mode("x", 1810.0, 0.03, 2e7), mode("y", 1200, 0.05, 1e7)]
    for name in ("m.toml", "m.json"):
        p, left_out = save_modes(tmp_path / name, given, source="tap")
        assert left_out == []
        ms = load_modes(p)
        assert ms.modes("x") == (
            ModalMode(1810.0, 0.03, 2e7, given[1].mass_kg),
            ModalMode(2600.0, 0.04, 3e7, given[0].mass_kg),
        )
        # Driving-point receptance by hand at 1810 Hz: mode 1 at resonance plus mode 2 below its.
        r2 = 1810.0 / 2600.0
        h = 1 / (2e7 * 2j * 0.03) + 1 / (3e7 * (1 - r2 * r2 + 2j * 0.04 * r2))
        assert ms.receptance("x", [1810.0])[0] == pytest.approx(h, rel=1e-12)
    with pytest.raises(Exception, match="no modes for direction 'z'"):
        ms.modes("z")
    # A tap in x, then one in y, saved into one file: the y tap replaces y and keeps x.
    p = tmp_path / "tool.toml"
    save_modes(p, given[:2], source="tap_x.csv")
    _, notes = save_modes(p, [mode("y", 1500.0, 0.02, 5e6)], source="tap_y.csv")
    assert notes == [f"{p}: kept direction(s) x of the earlier file"]
    ms = load_modes(p)
    assert [m.frequency_hz for m in ms.modes("x")] == [1810.0, 2600.0]
    assert [m.frequency_hz for m in ms.modes("y")] == [1500.0]
    assert ms.source == "tap_x.csv; tap_y.csv"


@pytest.mark.parametrize(
    ("line", "why"),
    [
        ("zeta = 1.5", "zeta = 1.5"),
        ("zeta = -0.01", "zeta = -0.01"),
        ("k_N_m = 4.0e7", "disagrees with m_kg"),
        ('f_hz = "1810"', "f_hz"),
        ("damping = 0.03", "unknown key"),
    ],
)
def test_load_refuses_bad_values_in_one_line_naming_the_place(tmp_path, line, why):
    from analysis.errors import CutlabError
    from analysis.modal import load_modes

    good = {"f_hz": "1810.0", "zeta": "0.03", "k_N_m": "2.0e7",
            "m_kg": f"{2e7 / (2 * math.pi * 1810) ** 2!r}"}  # fmt: skip
    key = line.split(" = ")[0]
    body = [f"{k} = {v}" for k, v in good.items() if k != key] + [line]
    text = 'format = "cutlab-modes"\nversion = 1\n\n[[modes.x]]\n' + "\n".join(body) + "\n"
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(CutlabError) as exc:
        load_modes(p)
    msg = str(exc.value)
    assert "\n" not in msg and why in msg and msg.startswith(f"{p}:")


def test_modes_files_use_the_catalogues_mode_schema_and_read_the_former_names(tmp_path):
    """One mode schema (issue 30): a saved file names f_hz, zeta, k_N_m, m_kg as the tool
    catalogue does; a file with the former names still loads, with a deprecation note."""
    from analysis.modal import load_modes, save_modes

    k, f = 2e7, 1810.0
    m = SimpleNamespace(channel="x", frequency_hz=f, damping_ratio=0.03, stiffness_n_m=k,
                        mass_kg=k / (2 * math.pi * f) ** 2)  # fmt: skip
    p, _ = save_modes(tmp_path / "new.toml", [m])
    text = p.read_text()
    assert "f_hz = 1810.0" in text and "zeta = 0.03" in text and "k_N_m" in text
    assert "frequency_hz" not in text.split("\n", 2)[2]  # the header comment aside
    old = tmp_path / "old.toml"
    old.write_text('format = "cutlab-modes"\nversion = 1\n\n[[modes.x]]\nfrequency_hz = 1810.0\n'
                   "damping_ratio = 0.03\n")  # fmt: skip
    with pytest.warns(FutureWarning, match="frequency_hz -> f_hz, damping_ratio -> zeta"):
        ms = load_modes(old)
    assert ms.modes("x")[0].f_hz == 1810.0 and ms.modes("x")[0].zeta == 0.03
