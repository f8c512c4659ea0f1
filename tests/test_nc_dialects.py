"""The dialect registry (planning.nc.dialects): one Dialect per controller, and every list of
dialect names in the house taken from it (the machine configs' names, the DNC protocols, the CLI
choices, planning.nc.DIALECTS)."""

from __future__ import annotations

import argparse

import pytest

from analysis.config import DIALECT_NAMES, load_machine
from planning import nc
from planning.nc import dialects
from planning.nc.dialects import REGISTRY, Dialect, get, names, protocols


def test_every_dialect_is_registered_under_its_own_name() -> None:
    assert names() == tuple(REGISTRY) == nc.DIALECTS
    for name, d in REGISTRY.items():
        assert isinstance(d, Dialect) and d.name == name and get(name) is d
        assert d.title and d.g_codes and d.m_codes
    assert names()[0] == dialects.DEFAULT


def test_an_unknown_dialect_names_the_known_ones() -> None:
    with pytest.raises(ValueError, match="expected one of " + ", ".join(names())):
        get("haas")


def test_the_machine_configs_accept_exactly_the_registry_names() -> None:
    """analysis cannot import planning: its list of names is a copy, checked here."""
    assert DIALECT_NAMES == names()
    m = load_machine("linuxcnc")
    assert m.dialect == "linuxcnc"
    with pytest.raises(ValueError, match="dialect"):
        type(m).model_validate({**m.model_dump(), "dialect": "haas"})


def test_the_dnc_protocols_are_the_registrys() -> None:
    from rig.dnc.port import PROTOCOLS

    assert PROTOCOLS == protocols()
    assert set(PROTOCOLS) <= {d.protocol for d in REGISTRY.values()}


def _dialect_choices(command: list[str]) -> list[str]:
    from rig.cli import build_parser

    parser = build_parser()
    for word in command:
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        parser = sub.choices[word]
    (action,) = [a for a in parser._actions if "--dialect" in a.option_strings]
    return list(action.choices)


@pytest.mark.parametrize(
    "command",
    [["nc", "check"], ["nc", "motions"], ["nc", "plot"], ["plan", "feed"], ["plan", "rough"],
     ["plan", "orient"]],  # fmt: skip
)
def test_every_dialect_option_offers_the_registry(command: list[str]) -> None:
    assert _dialect_choices(command) == list(names())


def test_each_dialect_knows_what_it_refuses_and_writes() -> None:
    """A few rules, read from the objects (what they mean is tested through the interpreter, the
    checker and the posts in test_nc_dialect*.py, test_nc_output.py, test_nc_rs274.py)."""
    fanuc, grbl, lcnc = get("fanuc"), get("grbl"), get("linuxcnc")
    assert fanuc.dwell_p_ms and not grbl.dwell_p_ms and not lcnc.dwell_p_ms
    assert lcnc.feed_before_units and not fanuc.feed_before_units
    assert 20 in lcnc.g10_l and 20 not in fanuc.g10_l
    assert lcnc.arc_spiral and not fanuc.arc_spiral
    assert grbl.firmware_model and 6 in grbl.refused_m and not fanuc.refused_m
    assert fanuc.post.keeps_tape and lcnc.post.wraps_percent and grbl.post.firmware_check
    assert (fanuc.protocol, grbl.protocol, lcnc.protocol) == ("fanuc", "grbl", None)
