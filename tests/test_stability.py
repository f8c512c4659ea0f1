"""Stability lobes (analysis.stability) against closed forms, an independent textbook formula and
an independent time-domain simulation.

The benchmark is Insperger, Stepan, Bayly & Mann 2003 (Multiple chatter frequencies in milling
processes, JSV 262) / Insperger & Stepan 2004 (IJNME 61:117-141): N = 2, Kt = 6e8 N/m^2,
Kn = 2e8 N/m^2, fn = 922 Hz, zeta = 0.011, m = 0.03993 kg, 5000-25000 rpm.

References used here, none computed by the code under test:
- the ZOA minimum of a 1-DOF slot: a_min = 2 k zeta (1 + zeta) / (N Kn / 4) (min of Re G is
  -1 / (4 k zeta (1 + zeta)), mean directional factor of a slot N Kn / 4);
- a slot with 4 teeth and a 1-DOF tool: the directional factor sum_j (Kt cos + Kn sin) sin over
  the two teeth in cut is Kn exactly at every instant (the sin 2 phi terms of teeth pi/2 apart
  cancel), so the delay equation is autonomous and its lobes are exactly the closed form
  a = -1 / (2 Kn Re G(w)), w tau = 3 pi + 2 atan2(Im G, Re G) + 2 pi k (Tlusty; Altintas
  2000 eq 3.30-3.35) -- the exact answer semi-discretization must converge to;
- Altintas & Budak 1995 / Altintas 2000 eqs 3.62-3.75 (alpha coefficients, the quadratic in
  Lambda) for the 2-DOF ZOA;
- an RK4 simulation of the delay equation written here, for the period-doubling lobes.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from analysis.errors import ConfigError
from analysis.stability import load_case, stability_lobes
from analysis.stability.sd import critical_depths, discretise
from analysis.stability.zoa import zoa_lobes, zoa_minimum

N_TEETH, KT, KN, FN, ZETA, MASS = 2, 6e8, 2e8, 922.0, 0.011, 0.03993
K_N_M = MASS * (2 * math.pi * FN) ** 2


def _toml(tmp_path, teeth=2, milling="down", ae=0.05, modes=("x",), points=200, extra=""):
    body = "".join(
        f'[[modes]]\naxis = "{d}"\nf_hz = {FN}\nzeta = {ZETA}\nm_kg = {MASS}\n' for d in modes
    )
    text = (
        f'[tool]\nteeth = {teeth}\n[cut]\nmilling = "{milling}"\nradial_immersion = {ae}\n'
        f"[coefficients]\nKtc_N_mm2 = {KT / 1e6}\nKrc_N_mm2 = {KN / 1e6}\n{body}"
        f"[spindle]\nrpm_min = 5000\nrpm_max = 25000\npoints = {points}\n{extra}"
    )
    p = tmp_path / "case.toml"
    p.write_text(text)
    return p


def _case(tmp_path, **kw):
    return load_case(_toml(tmp_path, **kw))


def _g(w):
    """1-DOF receptance, m/N."""
    r = w / (2 * math.pi * FN)
    return 1 / (K_N_M * (1 - r * r + 2j * ZETA * r))


def test_the_issue_number_of_the_slot_zoa_minimum_is_the_closed_form(tmp_path) -> None:
    a_min = 2 * K_N_M * ZETA * (1 + ZETA) / (N_TEETH * KN / 4)
    assert K_N_M == pytest.approx(1.340e6, rel=1e-3)
    assert a_min * 1e3 == pytest.approx(0.298, abs=0.0005)  # the issue's 0.298 mm
    case = _case(tmp_path, ae=1.0)
    assert zoa_minimum(case) == pytest.approx(a_min, rel=1e-4)
    fine = np.linspace(5000, 25000, 4000)
    depth, _ = zoa_lobes(case, fine)
    assert depth.min() == pytest.approx(a_min, rel=2e-3)  # every lobe's bottom touches it


def _slot4_lobe_points():
    """(rpm, depth m) on the exact lobes of the 1-DOF 4-tooth slot, near three lobe bottoms,
    where that lobe is the lowest."""
    w = 2 * math.pi * FN * np.array([1.015, 1.022, 1.03])
    g = _g(w)
    depth = -1 / (2 * KN * g.real)
    pts = []
    for k in (1, 2, 3):
        tau = (3 * math.pi + 2 * np.arctan2(g.imag, g.real) + 2 * math.pi * k) / w
        pts += [(60 / (4 * t), a) for t, a in zip(tau, depth)]
    return np.array(pts)


def test_semi_discretization_converges_to_the_exact_4_tooth_slot_lobes(tmp_path) -> None:
    case = _case(tmp_path, teeth=4, ae=1.0)
    pts = _slot4_lobe_points()
    case = dataclasses.replace(case, rpm=pts[:, 0])
    grid = np.geomspace(0.3 * pts[:, 1].min(), 10 * pts[:, 1].max(), 30)
    errors = []
    for m in (12, 24, 48):
        depth, _ = critical_depths(discretise(case, m), grid, iterations=8)
        errors.append(np.max(np.abs(depth / pts[:, 1] - 1)))
    assert errors[-1] < 2e-3, errors
    assert errors[1] < errors[0] / 4 and errors[2] < errors[1] / 4, errors  # >= second order
    # Ding et al.'s linear interpolation converges too, more slowly (second order)
    lin = [np.max(np.abs(critical_depths(discretise(case, m, order=1), grid, 8)[0] / pts[:, 1]
                         - 1)) for m in (24, 48)]  # fmt: skip
    assert lin[1] < lin[0] / 3 and lin[1] > errors[1]


def test_zoa_equals_sd_for_a_four_tooth_slot_2dof(tmp_path) -> None:
    case = _case(tmp_path, teeth=4, ae=1.0, modes=("x", "y"), points=60)
    zoa = stability_lobes(case, "zoa")
    sd = stability_lobes(case, "sd")
    both = np.isfinite(sd.depth_limit_mm) & np.isfinite(zoa.depth_limit_mm)
    assert both.sum() > 40
    assert np.array_equal(np.isfinite(sd.depth_limit_mm), np.isfinite(zoa.depth_limit_mm))
    err = np.abs(sd.depth_limit_mm[both] / zoa.depth_limit_mm[both] - 1)
    assert np.median(err) < 0.05  # the issue's 5 %
    assert np.median(err) < 0.005  # in fact: the 2-DOF 4-tooth slot is autonomous too
    assert zoa.warnings == []


def _altintas_zoa(case, w):
    """Altintas 2000 eqs 3.62-3.75: (rpm per lobe k = 0..K, a_lim m) at chatter w (rad/s)."""
    kr = KN / KT
    a, b = case.cut_angles_rad

    def alpha(p):
        return 0.5 * np.array([
            [math.cos(2 * p) - 2 * kr * p + kr * math.sin(2 * p),
             -math.sin(2 * p) - 2 * p + kr * math.cos(2 * p)],
            [-math.sin(2 * p) + 2 * p + kr * math.cos(2 * p),
             -math.cos(2 * p) - 2 * kr * p - kr * math.sin(2 * p)],
        ])  # fmt: skip

    al = alpha(b) - alpha(a)
    g = _g(w)
    a0 = g * g * (al[0, 0] * al[1, 1] - al[0, 1] * al[1, 0])
    a1 = al[0, 0] * g + al[1, 1] * g
    lam = np.stack([-(a1 + s * np.sqrt(a1 * a1 - 4 * a0)) / (2 * a0) for s in (1, -1)])
    kappa = lam.imag / lam.real
    a_lim = -2 * math.pi * lam.real * (1 + kappa**2) / (case.teeth * KT)
    eps = math.pi - 2 * np.arctan(kappa)
    return lam, a_lim, eps


def test_zoa_2dof_matches_altintas_formula(tmp_path) -> None:
    case = _case(tmp_path, ae=0.5, modes=("x", "y"))
    w = 2 * math.pi * FN * np.linspace(1.005, 1.06, 12)
    lam, a_lim, eps = _altintas_zoa(case, w)
    ok = (a_lim > 0) & np.isfinite(a_lim)
    rpm, want = [], []
    for k in (2, 3):
        tau = (eps + 2 * math.pi * k) / w
        rpm += list((60 / (case.teeth * tau))[ok])
        want += list(a_lim[ok])
    rpm, want = np.array(rpm), np.array(want)
    got, _ = zoa_lobes(case, np.sort(rpm))
    got = got[np.argsort(np.argsort(rpm))]
    # at each point the ZOA envelope is at or below that lobe, and on it where it is the lowest
    assert np.all(got <= want * (1 + 2e-3))
    assert np.median(np.abs(got / want - 1)) < 2e-3


def _simulate(case, rpm, depth_m, periods=240, per=200):
    """x at the start of each tooth period of the 1-DOF equation
    x'' + 2 zeta wn x' + wn^2 x = -(w / m) h(t) (x(t) - x(t - tau)), RK4 with delay = per steps
    (half steps by the mean of the neighbouring samples)."""
    tau = 60 / (case.teeth * rpm)
    dt = tau / per
    wn = 2 * math.pi * FN
    a, b = case.cut_angles_rad
    om = 2 * math.pi * rpm / 60

    def h(t):
        out = 0.0
        for j in range(case.teeth):
            p = (a + om * t + 2 * math.pi * j / case.teeth) % (2 * math.pi)
            if a <= p <= b:
                out += (KT * math.cos(p) + KN * math.sin(p)) * math.sin(p)
        return out * depth_m / MASS

    hist = [1e-6] * (per + 1)  # x on [-tau, 0]
    x, v = 1e-6, 0.0
    out = [x]
    c2, c1 = wn * wn, 2 * ZETA * wn
    for n in range(periods * per):
        t = n * dt
        d0, d2 = hist[-per - 1], hist[-per]
        d1 = 0.5 * (d0 + d2)

        def f(t_, x_, v_, d_):
            return v_, -c2 * x_ - c1 * v_ - h(t_) * (x_ - d_)

        k1 = f(t, x, v, d0)
        k2 = f(t + dt / 2, x + dt / 2 * k1[0], v + dt / 2 * k1[1], d1)
        k3 = f(t + dt / 2, x + dt / 2 * k2[0], v + dt / 2 * k2[1], d1)
        k4 = f(t + dt, x + dt * k3[0], v + dt * k3[1], d2)
        x += dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        v += dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        hist.append(x)
        if (n + 1) % per == 0:
            out.append(x)
    return np.array(out)


def test_low_immersion_flip_lobes_that_zoa_misses(tmp_path) -> None:
    """a/D = 0.05 down milling, 2 teeth: SD finds period-doubling lobes far below ZOA; an
    independent simulation agrees: stable at 0.9 and growing, sign alternating every tooth
    period, at 1.1 times SD's limit, where ZOA calls the cut stable."""
    case = _case(tmp_path, points=81)
    sd = stability_lobes(case, "sd")
    zoa = stability_lobes(case, "zoa")
    flip = np.array([k == "flip" for k in sd.kind])
    assert flip.sum() > 10
    ratio = sd.depth_limit_mm / zoa.depth_limit_mm
    assert ratio[flip].min() < 0.4
    assert zoa.warnings and "period-doubling" in zoa.warnings[0]
    assert sd.warnings == []
    # flip chatter: an odd multiple of half the tooth-passing frequency
    tpf = sd.spindle_rpm[flip] * case.teeth / 60
    harmonic = sd.chatter_hz[flip] / tpf - 0.5
    assert np.allclose(harmonic, np.round(harmonic), atol=1e-6)
    i = np.flatnonzero(flip)[np.argmin(ratio[flip])]
    rpm, lim = sd.spindle_rpm[i], sd.depth_limit_mm[i] / 1e3
    assert 1.1 * lim < zoa.depth_limit_mm[i] / 1e3
    below = _simulate(case, rpm, 0.9 * lim)
    above = _simulate(case, rpm, 1.1 * lim)
    assert np.abs(below[-40:]).max() < 0.5 * np.abs(below[40:80]).max()
    assert np.abs(above[-40:]).max() > 2 * np.abs(above[40:80]).max()
    tail = above[-20:]
    assert np.all(tail[1:] * tail[:-1] < 0)  # period doubling


@pytest.mark.parametrize("ae", [1.0, 0.5, 0.1, 0.05])
@pytest.mark.parametrize("milling", ["up", "down"])
def test_insperger_benchmark_converges(tmp_path, ae, milling) -> None:
    """The benchmark's lobes at 21 speeds: doubling the steps per period changes the limit by
    far less than halving them did (the discretisation converges), and 30 steps (the default)
    are within 1 % (median) of 60."""
    case = _case(tmp_path, ae=ae, milling=milling, points=21)
    d = {m: stability_lobes(case, "sd", m).depth_limit_mm for m in (15, 30, 60)}
    ok = np.isfinite(d[60])
    e15, e30 = (np.median(np.abs(d[m][ok] / d[60][ok] - 1)) for m in (15, 30))
    assert e30 < 0.01 and e30 < e15 / 4 + 1e-9


@pytest.mark.parametrize("teeth,ae", [(6, 0.25), (3, 0.75), (4, 0.5)])
@pytest.mark.parametrize("milling", ["up", "down"])
def test_a_cut_one_tooth_pitch_long_is_continuous_with_its_neighbours(
    tmp_path, teeth, ae, milling
) -> None:
    """A cut arc exactly one pitch long (6 flutes at a quarter immersion) has no tooth entering
    or leaving within the period; its round-off once made a free flight ~1e-13 of a period long
    and a zero limit. The limit is that of immersions 1e-6 either side, within 1 % (their
    discretisations differ: a break step near the period's end)."""
    lim = {
        d: stability_lobes(_case(tmp_path, teeth=teeth, ae=ae + d, milling=milling, points=9),
                           "sd").depth_limit_mm
        for d in (-1e-6, 0.0, 1e-6)
    }  # fmt: skip
    for d in (-1e-6, 1e-6):
        assert np.allclose(lim[0.0], lim[d], rtol=0.01), lim


def test_2dof_benchmark_low_immersion_has_flip_lobes_too(tmp_path) -> None:
    case = _case(tmp_path, ae=0.05, modes=("x", "y"), points=81)
    sd = stability_lobes(case, "sd")
    assert any(k == "flip" for k in sd.kind)
    assert "period-doubling" in stability_lobes(case, "zoa").warnings[0]


# ------------------------------------------------------------------------------------ config


@pytest.mark.parametrize(
    "old,new,words",
    [
        (
            "radial_immersion = 0.05",
            "radial_immersion = 1.5",
            ["radial_immersion", "1.5", ":5:", "ae/D"],
        ),
        ("teeth = 2", "teeth = 0", ["tool.teeth", "0"]),
        ('milling = "down"', 'milling = "climb"', ["cut.milling", "climb"]),
        ("m_kg = 0.03993", "m_kg = -1", ["m_kg", "-1", "kg"]),
        ("m_kg = 0.03993", "k_N_m = 1e6\nm_kg = 0.03993", ["exactly one"]),
        ("rpm_max = 25000", "rpm_max = 4000", ["rpm_max", "4000"]),
        ("Ktc_N_mm2 = 600.0", "Ktc_N_mm2 = 600.0\nKtc_ratio = 1", ["Ktc_ratio", "unknown key"]),
    ],
)
def test_bad_config_is_one_line_naming_the_field(tmp_path, old, new, words) -> None:
    p = _toml(tmp_path)
    p.write_text(p.read_text().replace(old, new))
    with pytest.raises(ConfigError) as exc:
        load_case(p)
    msg = str(exc.value)
    assert "\n" not in msg and str(p) in msg
    for w in words:
        assert w in msg


def test_coefficients_and_modes_from_files(tmp_path) -> None:
    import json

    (tmp_path / "forces.json").write_text(json.dumps(
        {"model": "endmill", "success": True,
         "coefficients": {"Ktc": 600.0, "Krc": 200.0, "Kac": 0.0}}))  # fmt: skip
    (tmp_path / "modal.json").write_text(json.dumps(
        {"modes": [{"axis": "x", "frequency_hz": FN, "damping_ratio": ZETA, "mass_kg": MASS},
                   {"axis": "z", "frequency_hz": 3000.0, "damping_ratio": 0.05}]}))  # fmt: skip
    p = tmp_path / "f.toml"
    p.write_text('coefficients_file = "forces.json"\nmodes_file = "modal.json"\n'
                 '[tool]\nteeth = 2\n[cut]\nmilling = "down"\nradial_immersion = 0.05\n'
                 "[spindle]\nrpm_min = 5000\nrpm_max = 25000\n")  # fmt: skip
    case = load_case(p)
    ref = _case(tmp_path)
    assert case.kt_n_m2 == ref.kt_n_m2 and case.kn_n_m2 == ref.kn_n_m2
    assert case.direction == ("x",) and case.k_n_m == pytest.approx(ref.k_n_m)
    # a force/force hammer test has no stiffness: one line saying so
    (tmp_path / "modal.json").write_text(json.dumps(
        {"modes": [{"axis": "x", "frequency_hz": FN, "damping_ratio": ZETA}]}))  # fmt: skip
    with pytest.raises(ConfigError, match=r"modal.json: mode 0 \(direction x\): stiffness"):
        load_case(p)


def test_saved_modes_file_is_read(tmp_path) -> None:
    from types import SimpleNamespace

    from analysis import modal

    mode = SimpleNamespace(channel="x", frequency_hz=FN, damping_ratio=ZETA,
                           stiffness_n_m=K_N_M, mass_kg=MASS)  # fmt: skip
    modal.save_modes(tmp_path / "m.toml", [mode])
    p = _toml(tmp_path)
    text = p.read_text()
    p.write_text('modes_file = "m.toml"\n' + text[: text.index("[[modes]]")]
                 + text[text.index("[spindle]") :])  # fmt: skip
    case = load_case(p)
    assert case.direction == ("x",) and case.k_n_m[0] == pytest.approx(K_N_M, rel=1e-6)
