"""planning.nc.dialects — one :class:`Dialect` per controller: its interpretation rules, its line
answers, what the posts write for it and its streaming protocol (:mod:`.base` says what each
rule means).

    from planning.nc.dialects import get, names
    d = get("linuxcnc"); d.feed_before_units, d.post.wraps_percent, d.protocol

Adding a controller: a module here with one ``DIALECT`` (see fanuc.py, grbl.py, linuxcnc.py) and
its line in :data:`REGISTRY`; the machine configs' names (``analysis.config.DIALECT_NAMES``: the
analysis layer cannot import this one) must list it too (tests/test_nc_dialects.py checks they
agree). Nothing outside this package compares dialect names (tests/test_layers.py).
"""

from __future__ import annotations

from planning.nc.dialects import fanuc, grbl, linuxcnc, mach3
from planning.nc.dialects.base import Answer, Dialect, LineRules, PostRules

#: name -> Dialect, in the order the names are listed (``--dialect`` choices, messages)
REGISTRY: dict[str, Dialect] = {
    d.name: d for d in (fanuc.DIALECT, grbl.DIALECT, linuxcnc.DIALECT, mach3.DIALECT)
}
DIALECTS: tuple[str, ...] = tuple(REGISTRY)
DEFAULT = fanuc.DIALECT.name  # without a machine: what the planners write


def names() -> tuple[str, ...]:
    """The dialect names, in registry order."""
    return DIALECTS


def get(name: str | Dialect) -> Dialect:
    """The dialect called ``name`` (a Dialect is returned as it is); ValueError naming the known
    ones otherwise."""
    if isinstance(name, Dialect):
        return name
    d = REGISTRY.get(name)
    if d is None:
        raise ValueError(f"dialect = {name!r}: expected one of {', '.join(DIALECTS)}")
    return d


get_dialect = get  # the name planning.nc's face exports


def protocols() -> tuple[str, ...]:
    """The ``rig.dnc`` streaming protocols of the dialects that have one, in registry order."""
    return tuple(dict.fromkeys(d.protocol for d in REGISTRY.values() if d.protocol))


def knowing_g(key: int) -> tuple[str, ...]:
    """The dialects that know G code ``key`` (ten times its number), in registry order."""
    return tuple(n for n, d in REGISTRY.items() if key in d.g_codes)


def titles() -> dict[str, str]:
    """name -> how messages name the control (``"linuxcnc"`` -> ``"LinuxCNC"``)."""
    return {n: d.title for n, d in REGISTRY.items()}


__all__ = [
    "Answer",
    "DEFAULT",
    "DIALECTS",
    "Dialect",
    "LineRules",
    "PostRules",
    "REGISTRY",
    "get",
    "get_dialect",
    "knowing_g",
    "names",
    "protocols",
    "titles",
]
