"""Feed rules: cutting load (percent, seed 001) -> feed (mm/min) in 20 load bins (seed 001 4.2).

Step 3 of seed 001's rule extraction. Given the minimum, base and maximum feed and the
load-to-feed relation, the relation is made linear by transforming the load axis, the transformed
axis is cut into 20 equal bins, and each bin gets its feed.

The relation. A feed rule keeps the removal rate per unit time near the reference cut's (seed 001
Fig. 9, "effective feed vs metal removal rate"): ``feed(L) = base x (L_ref / L) ** p`` with
``p = 1`` (constant removal rate) by default, ``L_ref`` the load of the base-feed test cut (e.g.
seed 001's 0.3 mm slot with a phi 30 ball) and ``p`` configurable. It is hyperbolic in L; on the
transformed axis ``u = (L_ref / L) ** p`` it is the straight line ``feed = base x u``.

The bins. ``u`` runs from ``min/base`` to ``max/base``; its bin edges are evenly spaced and hit
``min``, ``base`` and ``max`` exactly (the reference point is a bin edge; the bins on each side of
it are of equal width, the two widths differing only by where the reference falls: seed 001 gives
178.6 and 180 mm/min). Each bin gets the feed of its heavier-load edge, so within the covered range
``load x feed`` never exceeds ``L_ref x base`` (for ``p = 1``): the rule may slow a cut but never
lets the removal rate per unit time rise above the reference. The reference load is the upper edge
of the base-feed bin, so ``feed_for(L_ref) == base``. The first bin (lightest load, fastest) starts
at 0 %, the last (slowest, the machine's minimum feed) ends at +inf %, so the bins cover every load
with no gap or overlap, and feeds fall monotonically with load within [min, max].

Rule file (TOML), small and readable::

    [rule]
    name = "gm241-phi30-ball-slot"
    min_feed_mm_min = 100.0
    base_feed_mm_min = 1000.0
    max_feed_mm_min = 3500.0
    reference_load_pct = 0.1323
    exponent = 1.0
    tool = "phi30-ball"  # optional: the tool of the test cuts (loads are relative to it)

    [[bins]]            # 20 of them, lightest load first
    load_min_pct = 0.0
    load_max_pct = 0.0383
    feed_mm_min = 3500.0
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w
from numpy.typing import ArrayLike, NDArray
from pydantic import Field, model_validator

from analysis.errors import AnalysisError, ConfigError
from analysis.validation import Model, read_toml, validate

N_BINS = 20


class _BinModel(Model):
    load_min_pct: float = Field(ge=0, description="%, cutting load")
    # inf ends the last bin; gt=0 still refuses NaN
    load_max_pct: float = Field(
        gt=0, allow_inf_nan=True, description="%, cutting load (inf for the last bin)"
    )
    feed_mm_min: float = Field(gt=0, description="mm/min")


class _RuleHeader(Model):
    name: str = Field(min_length=1)
    description: str = ""
    min_feed_mm_min: float = Field(gt=0, description="mm/min")
    base_feed_mm_min: float = Field(gt=0, description="mm/min")
    max_feed_mm_min: float = Field(gt=0, description="mm/min")
    reference_load_pct: float = Field(gt=0, description="%, load of the base-feed test cut")
    exponent: float = Field(1.0, gt=0, le=5, description="p in feed = base (L_ref/L)^p")
    source: str = Field("", description="where the rule came from (runs, hand-made)")
    tool: str = Field("", description="tool of the test cuts (configs/tools.toml name)")

    @model_validator(mode="after")
    def _ordered(self) -> _RuleHeader:
        lo, base, hi = self.min_feed_mm_min, self.base_feed_mm_min, self.max_feed_mm_min
        if not lo <= base <= hi or lo == hi:
            raise ValueError(
                f"feeds must satisfy min <= base <= max and min < max (mm/min): got "
                f"min {lo}, base {base}, max {hi}"
            )
        return self


class _RuleFile(Model):
    rule: _RuleHeader
    bins: tuple[_BinModel, ...] = Field(min_length=1)


@dataclass(frozen=True, eq=False)
class FeedRule:
    """A load -> feed rule: ``n`` contiguous load intervals ``(lo, hi]``, each with one feed.

    ``load_edges_pct`` has n+1 increasing entries from 0 to +inf; ``feeds_mm_min`` has n entries,
    non-increasing, all within [min, max]. A load equal to an edge belongs to the bin below it.
    """

    name: str
    min_feed_mm_min: float
    base_feed_mm_min: float
    max_feed_mm_min: float
    reference_load_pct: float
    load_edges_pct: NDArray[np.float64]
    feeds_mm_min: NDArray[np.float64]
    exponent: float = 1.0
    description: str = ""
    source: str = ""
    tool: str = ""  # the tool the rule was derived with (loads are relative to it); "" unknown
    meta: dict[str, Any] = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        _check_bins(self, where=f"rule '{self.name}'")

    @property
    def n_bins(self) -> int:
        return len(self.feeds_mm_min)

    def feed_for(self, load_pct: ArrayLike) -> NDArray[np.float64]:
        """Feed, mm/min, for each cutting load (percent). Vectorised; load must be >= 0."""
        load = np.asarray(load_pct, dtype=float)
        if np.any(~(load >= 0)):
            i = int(np.argmax(~(load >= 0).ravel()))
            raise AnalysisError(f"load_pct[{i}] = {load.ravel()[i]}: must be >= 0 (%)")
        return self.feeds_mm_min[self.bin_of(load)]

    def bin_of(self, load_pct: ArrayLike) -> NDArray[np.intp]:
        """Bin index (0 = lightest load) of each load."""
        load = np.asarray(load_pct, dtype=float)
        idx = np.searchsorted(self.load_edges_pct, load, side="left") - 1
        return np.clip(idx, 0, self.n_bins - 1)

    def relation(self, load_pct: ArrayLike) -> NDArray[np.float64]:
        """The continuous relation the bins approximate, clamped to [min, max], mm/min."""
        load = np.maximum(np.asarray(load_pct, dtype=float), 1e-300)
        f = self.base_feed_mm_min * (self.reference_load_pct / load) ** self.exponent
        out: NDArray[np.float64] = np.clip(f, self.min_feed_mm_min, self.max_feed_mm_min)
        return out

    def table(self) -> list[dict[str, float]]:
        """One dict per bin: load_min_pct, load_max_pct, feed_mm_min."""
        e, f = self.load_edges_pct, self.feeds_mm_min
        return [
            {
                "bin": i,
                "load_min_pct": float(e[i]),
                "load_max_pct": float(e[i + 1]),
                "feed_mm_min": float(f[i]),
            }
            for i in range(self.n_bins)
        ]


def _check_bins(rule: FeedRule, where: str) -> None:
    e, f = np.asarray(rule.load_edges_pct, float), np.asarray(rule.feeds_mm_min, float)
    if e.ndim != 1 or f.ndim != 1 or len(e) != len(f) + 1 or len(f) < 1:
        raise ConfigError(f"{where}: needs n feeds and n+1 load edges, got {len(f)} and {len(e)}")
    if e[0] != 0:
        raise ConfigError(
            f"{where}: bins[0].load_min_pct = {e[0]}: the first bin must start at 0 %"
        )
    if not math.isinf(e[-1]):
        raise ConfigError(
            f"{where}: bins[{len(f) - 1}].load_max_pct = {e[-1]}: the last bin must end at inf %"
        )
    for i in range(len(f)):
        if not e[i + 1] > e[i]:
            raise ConfigError(
                f"{where}: bins[{i}] load {e[i]}..{e[i + 1]} %: load_max_pct must exceed "
                "load_min_pct"
            )
        if not rule.min_feed_mm_min - 1e-9 <= f[i] <= rule.max_feed_mm_min + 1e-9:
            raise ConfigError(
                f"{where}: bins[{i}].feed_mm_min = {f[i]}: outside [{rule.min_feed_mm_min}, "
                f"{rule.max_feed_mm_min}] mm/min"
            )
        if i and f[i] > f[i - 1]:
            raise ConfigError(
                f"{where}: bins[{i}].feed_mm_min = {f[i]} exceeds bins[{i - 1}]'s {f[i - 1]}: "
                "feeds must not rise with load (mm/min)"
            )


def _representative_feeds(lo: float, base: float, hi: float, n: int) -> NDArray[np.float64]:
    """n feeds from ``hi`` down to ``lo`` through ``base``, evenly spaced on each side of it."""
    if hi == base or lo == base:
        return np.linspace(hi, lo, n)
    k = int(round((hi - base) / (hi - lo) * (n - 1)))
    k = min(max(k, 1), n - 2)  # keep base strictly inside so both sides have a bin
    upper = np.linspace(hi, base, k + 1)
    lower = np.linspace(base, lo, n - k)
    return np.concatenate([upper, lower[1:]])


def derive_rule(
    name: str,
    min_feed_mm_min: float,
    base_feed_mm_min: float,
    max_feed_mm_min: float,
    reference_load_pct: float,
    exponent: float = 1.0,
    n_bins: int = N_BINS,
    description: str = "",
    source: str = "",
    tool: str = "",
) -> FeedRule:
    """Seed 001 step 3: the load axis transformed so feed is linear in it, cut into ``n_bins``.

    See the module docstring for the transformation and how the bins are placed.
    """
    # A base within rounding of a limit is that limit: bins a few ulps wide would be empty, and
    # the reference load must fall exactly on the base feed's edge.
    for limit in (min_feed_mm_min, max_feed_mm_min):
        if math.isclose(base_feed_mm_min, limit, rel_tol=1e-9):
            base_feed_mm_min = limit
    hdr = validate(
        _RuleHeader,
        dict(
            name=name,
            min_feed_mm_min=min_feed_mm_min,
            base_feed_mm_min=base_feed_mm_min,
            max_feed_mm_min=max_feed_mm_min,
            reference_load_pct=reference_load_pct,
            exponent=exponent,
            description=description,
            source=source,
            tool=tool,
        ),
        where=f"rule '{name}'",
    )
    if not 3 <= n_bins <= 200:
        raise AnalysisError(f"n_bins = {n_bins}: expected 3..200 (seed 001 uses 20)")
    lo, base, hi = hdr.min_feed_mm_min, hdr.base_feed_mm_min, hdr.max_feed_mm_min
    feeds = _representative_feeds(lo, base, hi, n_bins)
    # Bin j's heavier edge is where the relation gives feed_j: L = L_ref (base / feed_j)^(1/p).
    upper = hdr.reference_load_pct * (base / feeds[:-1]) ** (1.0 / hdr.exponent)
    edges = np.concatenate([[0.0], upper, [np.inf]])
    return FeedRule(
        name=hdr.name,
        min_feed_mm_min=hdr.min_feed_mm_min,
        base_feed_mm_min=hdr.base_feed_mm_min,
        max_feed_mm_min=hdr.max_feed_mm_min,
        reference_load_pct=hdr.reference_load_pct,
        load_edges_pct=edges,
        feeds_mm_min=feeds,
        exponent=hdr.exponent,
        description=hdr.description,
        source=hdr.source,
        tool=hdr.tool,
    )


def rule_to_toml(rule: FeedRule) -> str:
    """The rule as TOML text (the rule file format in the module docstring)."""
    header = {
        "name": rule.name,
        "description": rule.description,
        "min_feed_mm_min": rule.min_feed_mm_min,
        "base_feed_mm_min": rule.base_feed_mm_min,
        "max_feed_mm_min": rule.max_feed_mm_min,
        "reference_load_pct": rule.reference_load_pct,
        "exponent": rule.exponent,
        "source": rule.source,
    }
    if rule.tool:
        header["tool"] = rule.tool
    bins = [
        {
            "load_min_pct": float(r["load_min_pct"]),
            "load_max_pct": float(r["load_max_pct"]),
            "feed_mm_min": float(r["feed_mm_min"]),
        }
        for r in rule.table()
    ]
    return tomli_w.dumps({"rule": header, "bins": bins})


def save_rule(rule: FeedRule, path: str | Path) -> Path:
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(rule_to_toml(rule), encoding="utf-8")
    return p


def rule_from_toml(text: str, where: str = "<rule>") -> FeedRule:
    """Parse and validate rule TOML text; errors name ``where``, the field and the value."""
    import tomllib

    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{where}: not valid TOML: {exc}") from None
    model = validate(_RuleFile, data, where, text)
    edges = [model.bins[0].load_min_pct]
    for i, b in enumerate(model.bins):
        if i and b.load_min_pct != model.bins[i - 1].load_max_pct:
            kind = "gap" if b.load_min_pct > model.bins[i - 1].load_max_pct else "overlap"
            raise ConfigError(
                f"{where}: bins[{i}].load_min_pct = {b.load_min_pct}: {kind} after bins[{i - 1}]"
                f".load_max_pct = {model.bins[i - 1].load_max_pct} (bins must be contiguous, %)"
            )
        edges.append(b.load_max_pct)
    h = model.rule
    try:
        return FeedRule(
            name=h.name,
            min_feed_mm_min=h.min_feed_mm_min,
            base_feed_mm_min=h.base_feed_mm_min,
            max_feed_mm_min=h.max_feed_mm_min,
            reference_load_pct=h.reference_load_pct,
            load_edges_pct=np.array(edges, float),
            feeds_mm_min=np.array([b.feed_mm_min for b in model.bins], float),
            exponent=h.exponent,
            description=h.description,
            source=h.source,
            tool=h.tool,
        )
    except ConfigError as exc:
        raise ConfigError(str(exc).replace(f"rule '{h.name}'", where, 1)) from None


def load_rule(path: str | Path) -> FeedRule:
    """Read a rule file; a malformed one raises ConfigError naming file, field and value."""
    _, text = read_toml(path)
    return rule_from_toml(text, str(path))


def plot_rule(rule: FeedRule, path: str | Path, loads_pct: ArrayLike | None = None) -> Path:
    """PNG of the rule: the continuous relation and the 20 bins' feeds (load on a log axis)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    e = rule.load_edges_pct
    lo = e[1] / 3
    hi = e[-2] * 3
    x = np.geomspace(lo, hi, 400)
    fig, ax = plt.subplots(figsize=(7, 4.2))
    ax.plot(x, rule.relation(x), color="0.6", lw=1, label=f"relation p={rule.exponent:g}")
    xs = np.concatenate([[lo], e[1:-1], [hi]])
    ax.stairs(rule.feeds_mm_min, xs, color="C0", lw=2, label=f"{rule.n_bins} bins")
    ax.axvline(rule.reference_load_pct, color="C3", ls="--", lw=1, label="reference load")
    ax.axhline(rule.base_feed_mm_min, color="C3", ls=":", lw=1)
    if loads_pct is not None:
        loads = np.asarray(loads_pct, float)
        ax.plot(loads, rule.feed_for(loads), "k.", ms=3, label="blocks")
    ax.set_xscale("log")
    ax.set_xlabel("cutting load, % (seed 001)")
    ax.set_ylabel("feed, mm/min")
    ax.set_title(f"feed rule {rule.name}")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    p = Path(path)
    fig.savefig(p, dpi=110)
    plt.close(fig)
    return p
