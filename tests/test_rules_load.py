"""Seed 001 cutting load and the 20-bin feed rules."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from analysis.errors import AnalysisError, ConfigError
from analysis.rules.load import cutting_load_percent, groove_area_mm2, slot_load_percent
from analysis.rules.rule import (
    derive_rule,
    load_rule,
    plot_rule,
    rule_from_toml,
    rule_to_toml,
    save_rule,
)


def test_load_formulas_match_seed001_definition() -> None:
    # A 10 mm flat end mill, flute 20 mm, full slot 2 mm deep over 50 mm: 10*2*50 removed.
    load = cutting_load_percent([1000.0], [50.0], [False], 10.0, 20.0)
    assert load[0] == pytest.approx(1000 / (20 * 10 * 50) * 100)  # = 10 %
    # A plunge of 5 mm with the same tool removing the full cylinder: 100 %.
    vol = math.pi * 25 * 5
    assert cutting_load_percent(vol, 5.0, True, 10.0, 20.0) == pytest.approx(100.0)
    # Zero-length move: load 0, not NaN.
    assert cutting_load_percent(0.0, 0.0, False, 10.0, 20.0) == 0.0


def test_load_rejects_bad_input() -> None:
    with pytest.raises(AnalysisError, match="removed_mm3"):
        cutting_load_percent([-1.0], [1.0], [False], 10, 20)
    with pytest.raises(AnalysisError, match="tool_diameter_mm = 0"):
        cutting_load_percent([1.0], [1.0], [False], 0, 20)


def test_groove_areas_closed_forms() -> None:
    assert groove_area_mm2("flat", 10, 2) == 20
    # Ball at full radius depth: half disc.
    assert groove_area_mm2("ball", 10, 5) == pytest.approx(math.pi * 25 / 2)
    # Bull r=2, D=10 at depth 2: flat 6*2 + two quarter discs (pi r^2 / 2).
    assert groove_area_mm2("bull", 10, 2, 2) == pytest.approx(12 + math.pi * 4 / 2)
    # Bull deeper than its corner radius adds the straight flanks.
    assert groove_area_mm2("bull", 10, 3, 2) == pytest.approx(6 * 3 + math.pi * 2 + 10 * 1)


@pytest.fixture()
def seed001_rule():
    ref = slot_load_percent("ball", 30, 0.3, 30)
    return derive_rule("gm241-phi30-slot", 100, 1000, 3500, ref)


def test_rule_has_20_contiguous_monotone_bins_within_limits(seed001_rule) -> None:
    r = seed001_rule
    e, f = r.load_edges_pct, r.feeds_mm_min
    assert r.n_bins == 20 and len(e) == 21
    assert e[0] == 0 and math.isinf(e[-1]) and np.all(np.diff(e) > 0)  # no gap, no overlap
    assert np.all(np.diff(f) <= 0)  # higher load -> lower or equal feed
    assert f[0] == 3500 and f[-1] == 100 and f.min() >= 100 and f.max() <= 3500
    assert r.feed_for(r.reference_load_pct) == 1000  # base feed at the reference load
    # Every load falls in exactly one bin.
    loads = np.geomspace(1e-6, 1e3, 5000)
    b = r.bin_of(loads)
    assert np.all((e[b] < loads) | ((b == 0) & (loads <= e[1])))
    assert np.all(loads <= e[b + 1])


def test_rule_never_raises_removal_rate_above_reference(seed001_rule) -> None:
    r = seed001_rule
    loads = np.geomspace(1e-5, r.load_edges_pct[-2], 20000)
    assert np.max(loads * r.feed_for(loads)) <= r.reference_load_pct * 1000 * (1 + 1e-12)


@settings(max_examples=60, deadline=None)
@given(
    lo=st.floats(1, 500),
    base_frac=st.floats(0.0, 1.0),
    span=st.floats(1.5, 50),
    ref=st.floats(1e-3, 50),
    p=st.floats(0.3, 3),
    n=st.integers(3, 40),
)
# A base feed one ulp below the maximum once gave a bin of zero width.
@example(lo=1.0, base_frac=0.9999999999999999, span=4.0, ref=1.0, p=3.0, n=3)
@example(lo=1.0, base_frac=0.9999999999999999, span=2.00001, ref=1.0, p=1.0, n=3)
@example(lo=70.91615572702608, base_frac=1.0, span=30.0, ref=1.0, p=1.0, n=3)  # base > max by 1 ulp
def test_rule_properties_hold_for_any_limits(lo, base_frac, span, ref, p, n) -> None:
    hi = lo * span
    base = lo + base_frac * (hi - lo)  # may step an ulp past max: derive_rule snaps it
    r = derive_rule("h", lo, base, hi, ref, exponent=p, n_bins=n)
    assert np.all(np.diff(r.load_edges_pct) > 0)
    assert np.all(np.diff(r.feeds_mm_min) <= 1e-9)
    assert r.feeds_mm_min.max() <= hi * (1 + 1e-12) and r.feeds_mm_min.min() >= lo * (1 - 1e-12)
    assert r.feed_for(ref) == pytest.approx(base)
    again = rule_from_toml(rule_to_toml(r))
    np.testing.assert_array_equal(again.load_edges_pct, r.load_edges_pct)
    np.testing.assert_array_equal(again.feeds_mm_min, r.feeds_mm_min)


def test_rule_file_round_trip_and_plot(tmp_path, seed001_rule) -> None:
    p = save_rule(seed001_rule, tmp_path / "r.toml")
    r = load_rule(p)
    np.testing.assert_array_equal(r.feeds_mm_min, seed001_rule.feeds_mm_min)
    png = plot_rule(r, tmp_path / "r.png", loads_pct=[0.05, 0.2])
    assert png.stat().st_size > 5000 and png.read_bytes()[:4] == b"\x89PNG"


def _bad(tmp_path, seed001_rule, old: str, new: str):
    text = rule_to_toml(seed001_rule)
    assert old in text
    p = tmp_path / "bad.toml"
    head, _, tail = text.rpartition(old)  # the last occurrence: the bins come after the header
    p.write_text(head + new + tail)
    return p


def test_rule_with_gap_is_rejected_naming_file_field_value(tmp_path, seed001_rule) -> None:
    e1 = repr(float(seed001_rule.load_edges_pct[1]))
    text = rule_to_toml(seed001_rule)
    # Shift bins[1].load_min_pct up: a gap after bins[0].
    i = text.index(f"load_min_pct = {e1}")
    p = tmp_path / "gap.toml"
    p.write_text(text[:i] + "load_min_pct = 0.039" + text[i + len(f"load_min_pct = {e1}") :])
    with pytest.raises(ConfigError, match=r"gap.toml: bins\[1\]\.load_min_pct = 0.039: gap"):
        load_rule(p)


def test_rule_with_rising_feed_or_bad_header_rejected(tmp_path, seed001_rule) -> None:
    p = _bad(tmp_path, seed001_rule, "feed_mm_min = 100.0", "feed_mm_min = 5000.0")
    with pytest.raises(ConfigError, match=r"bins\[19\]\.feed_mm_min = 5000.0: outside"):
        load_rule(p)
    p = _bad(tmp_path, seed001_rule, "base_feed_mm_min = 1000.0", "base_feed_mm_min = 9000.0")
    with pytest.raises(ConfigError, match="min <= base <= max"):
        load_rule(p)
    p = _bad(tmp_path, seed001_rule, "exponent = 1.0", "exponent = 1.0\ncolour = 3")
    with pytest.raises(ConfigError, match=r"bad.toml:\d+: rule.colour = 3: unknown key"):
        load_rule(p)
