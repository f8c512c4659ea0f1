"""Which file column is cutlab's x, y and z force, and whether the end-mill fit agrees.

cutlab's frame (Altintas, Manufacturing Automation): x the feed direction, y cross-feed, z along
the tool axis; forces are those on the workpiece (a table dynamometer's). A mapping
``x=-Fy,y=Fx,z=-Fz`` names, for each axis, a column of the file (case-insensitive, a unit
suffix such as ``[N]`` ignored) with an optional minus sign.

:func:`check_axes` refits the end-mill model under all 48 signed permutations of (x, y, z) and
refuses, with the figures, a mapping that yields a negative cutting coefficient (Ktc, Krc, Kac)
or fits clearly worse than another; it warns when the runs cannot tell the mapping from one that
gives K_tc > K_rc while the given one gives K_rc > K_tc. :func:`choose_axes` (``--axes auto``)
picks the best-fitting mapping with positive cutting coefficients when the runs tell it from the
runner-up, and refuses when they cannot (a slot-only sweep cannot tell x from y).
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TypedDict

import numpy as np

from analysis.config import Dynamometer, EndMill
from analysis.errors import AnalysisError
from analysis.forces.endmill import PARAMETERS, mean_force_design
from analysis.identify._common import RunAverage
from analysis.identify._linear import linear_fit
from analysis.identify.endmill import _cut

__all__ = ["AxesCandidate", "AxesCheck", "AxesChoice", "AxisMap", "check_axes", "choose_axes",
           "column_key", "parse_axes"]  # fmt: skip

#: Another mapping is "clearly better" when its residual RMS is below this fraction of the given's.
BETTER_RESIDUAL_RATIO = 0.5
_SHORT = ("Ktc", "Krc", "Kac", "Kte", "Kre", "Kae")


def column_key(name: str) -> str:
    """A column name compared without case, spaces and a unit suffix: 'Fx [N]' -> 'fx'."""
    base = re.sub(r"\s*[\[(][^\])]*[\])]\s*$", "", name.strip())
    return re.sub(r"[\s_]+", " ", base).strip().lower()


# Default names of the force columns per axis (after column_key), e.g. 'Fx', 'Kraft X', 'x'.
_DEFAULT = re.compile(r"^(?:f|force|kraft|force |kraft )?(?P<axis>[xyz])(?: n)?$")


@dataclass(frozen=True)
class AxisMap:
    """For cutlab's x, y, z: the source column name and its sign (+1 or -1)."""

    sources: tuple[str, str, str]
    signs: tuple[float, float, float] = (1.0, 1.0, 1.0)

    @property
    def text(self) -> str:
        return ",".join(
            f"{ax}={'-' if s < 0 else ''}{src}"
            for ax, src, s in zip("xyz", self.sources, self.signs)
        )

    def columns(self, names: Sequence[str], where: str) -> list[tuple[int, float]]:
        """(column index, sign) for x, y, z among ``names``; an unknown column is an error."""
        keys = [column_key(n) for n in names]
        out = []
        for ax, src, s in zip("xyz", self.sources, self.signs):
            k = column_key(src)
            if k not in keys:
                raise AnalysisError(
                    f"{where}: axes {self.text}: {ax} = {src!r} is not a column "
                    f"(columns: {', '.join(names)})"
                )
            out.append((keys.index(k), s))
        return out

    def matrix(self, names: Sequence[str], where: str) -> np.ndarray:
        """(3, len(names)) signed selection: cutlab forces = M @ the columns' values."""
        m = np.zeros((3, len(names)))
        for ax, (k, s) in enumerate(self.columns(names, where)):
            m[ax, k] = s
        return m

    @classmethod
    def default(cls, names: Sequence[str], dyno: Dynamometer | None = None) -> AxisMap | None:
        """The rig config's mapping (``axes`` or its channels' name, axis, sign) when its names
        are columns, else columns named like Fx, Fy, Fz ('Fx [N]', 'Kraft X', 'x'); None when
        neither gives all three axes."""
        keys = [column_key(n) for n in names]
        if dyno is not None:
            if dyno.axes:
                m = parse_axes(dyno.axes, "rig config: dynamometer.axes")
                if all(column_key(s) in keys for s in m.sources):
                    return m
            found: dict[int, tuple[str, float]] = {}
            for ch in dyno.channels:
                if column_key(ch.name) in keys:
                    found["xyz".index(ch.axis)] = (ch.name, float(ch.sign))
            if len(found) == 3:
                return cls((found[0][0], found[1][0], found[2][0]),
                           (found[0][1], found[1][1], found[2][1]))  # fmt: skip
        by_axis: dict[str, str] = {}
        for n, k in zip(names, keys):
            hit = _DEFAULT.match(k)
            if hit and hit.group("axis") not in by_axis:
                by_axis[hit.group("axis")] = n
        if len(by_axis) == 3:
            return cls((by_axis["x"], by_axis["y"], by_axis["z"]))
        return None

    def composed(self, perm: Sequence[int], flips: Sequence[float]) -> AxisMap:
        """This mapping with x, y, z taken from ``perm`` of its own axes, signs times ``flips``."""
        return AxisMap(
            tuple(self.sources[p] for p in perm),  # type: ignore[arg-type]
            tuple(self.signs[p] * f for p, f in zip(perm, flips)),  # type: ignore[arg-type]
        )


_ITEM = re.compile(r"^\s*([xyzXYZ])\s*=\s*([+-]?)\s*(\S(?:.*\S)?)\s*$")


def parse_axes(text: str, where: str = "--axes") -> AxisMap:
    """``x=-Fy,y=Fx,z=-Fz`` -> AxisMap; each of x, y, z exactly once."""
    got: dict[str, tuple[str, float]] = {}
    for item in str(text).split(","):
        m = _ITEM.match(item)
        if not m:
            raise AnalysisError(
                f"{where} {text!r}: {item.strip()!r} is not AXIS=COLUMN; expected e.g. "
                "x=-Fy,y=Fx,z=-Fz (x feed, y cross-feed, z tool axis; '-' flips the sign)"
            )
        ax = m.group(1).lower()
        if ax in got:
            raise AnalysisError(f"{where} {text!r}: {ax} given twice")
        got[ax] = (m.group(3), -1.0 if m.group(2) == "-" else 1.0)
    missing = [a for a in "xyz" if a not in got]
    if missing:
        raise AnalysisError(
            f"{where} {text!r}: no column for {', '.join(missing)}; expected x=..,y=..,z=.."
        )
    return AxisMap(
        (got["x"][0], got["y"][0], got["z"][0]), (got["x"][1], got["y"][1], got["z"][1])
    )


def remap(avg: RunAverage, m: np.ndarray) -> RunAverage:
    """A revolution average with its forces taken through the (3, 3) matrix ``m`` (the average
    and the offsets are linear in the forces; the steady window depends on the resultant only,
    which a signed permutation keeps)."""
    return replace(avg, waveform_n=avg.waveform_n @ m.T, mean_n=m @ avg.mean_n,
                   offset_n=m @ avg.offset_n,
                   revolution_means_n=avg.revolution_means_n @ m.T)  # fmt: skip


def _fmt(c: dict[str, float]) -> str:
    return ", ".join(f"{k} {v:.4g}" for k, v in c.items())


#: The 48 signed permutations of (x, y, z): (perm, signs) with cutlab axis i = signs[i] times
#: the mapping's axis perm[i].
SIGNED_PERMUTATIONS = tuple(
    (perm, signs)
    for perm in itertools.permutations(range(3))
    for signs in itertools.product((1.0, -1.0), repeat=3)
)
#: Cutting coefficients that are positive under the right mapping (forces on the workpiece: the
#: tangential force drags it with the tooth, the radial one pushes it away, the axial one follows
#: the helix); the edge terms may come out slightly negative from noise.
CUTTING = ("Ktc", "Krc", "Kac")


class AxesCandidate(TypedDict):
    """The end-mill fit under one mapping (N)."""

    axes: str
    r_squared: float
    residual_rms_n: float
    coefficients: dict[str, float]
    plausible: bool


class AxesCheck(TypedDict):
    """:func:`check_axes`: the mapping, every candidate, warnings, the refusal (or None)."""

    axes: str
    candidates: list[AxesCandidate]
    warnings: list[str]
    refusal: str | None
    checked: bool


class AxesChoice(TypedDict):
    """:func:`choose_axes`: the chosen mapping, its fit, the runner-up's, every candidate and
    the line that says it."""

    axes: str
    chosen: AxesCandidate
    runner_up: AxesCandidate | None
    candidates: list[AxesCandidate]
    line: str


def _candidates(averages: Sequence[RunAverage], tool: EndMill,
                axes: AxisMap) -> list[AxesCandidate] | None:  # fmt: skip
    """The end-mill fit under each of the 48 signed permutations of ``axes`` (the given one
    first); None when the runs cannot be fitted at all (too few, rank-deficient)."""
    X = np.concatenate([mean_force_design(tool, _cut(tool, a.conditions)) for a in averages])
    y = np.stack([a.mean_n for a in averages])
    out: list[AxesCandidate] = []
    for perm, signs in SIGNED_PERMUTATIONS:
        m = np.zeros((3, 3))
        for ax, (p, f) in enumerate(zip(perm, signs)):
            m[ax, p] = f
        try:
            fit, _ = linear_fit(X, (y @ m.T).ravel(), PARAMETERS)
        except AnalysisError:
            return None
        coef = {s: float(v) for s, v in zip(_SHORT, fit.values)}
        out.append({
            "axes": axes.composed(perm, signs).text,
            "r_squared": float(fit.r_squared),
            "residual_rms_n": float(fit.residual_rms),
            "coefficients": coef,
            "plausible": all(coef[k] > 0 for k in CUTTING),
        })  # fmt: skip
    return out


def _describe(c: AxesCandidate) -> str:
    return (f"{c['axes']}: {_fmt(c['coefficients'])}, R^2 {c['r_squared']:.5f}, "
            f"residual {c['residual_rms_n']:.3g} N")  # fmt: skip


def _ranked(cands: list[AxesCandidate]) -> list[AxesCandidate]:
    """The plausible mappings (all cutting coefficients positive), best fit first."""
    return sorted((c for c in cands if c["plausible"]), key=lambda c: c["residual_rms_n"])


def _tells(best: AxesCandidate, runner: AxesCandidate | None) -> bool:
    """Whether the runs tell the best mapping from the runner-up: its residual at least
    1 / BETTER_RESIDUAL_RATIO times the best's (slots alone cannot: x = F1, y = F2 and
    x = -F2, y = F1 fit them alike, K_tc and K_rc traded)."""
    return runner is None or (best["residual_rms_n"]
                              < BETTER_RESIDUAL_RATIO * runner["residual_rms_n"])  # fmt: skip


def check_axes(
    averages: Sequence[RunAverage], tool: EndMill, axes: AxisMap, refuse: bool = True
) -> AxesCheck:
    """Fit the end-mill model under ``axes`` and the 47 other signed permutations. Returns
    ``{"axes", "candidates": [{axes, r_squared, residual_rms_n, coefficients, plausible}],
    "warnings": [...], "refusal": str | None, "checked": bool}``: a refusal (one line) when the
    mapping gives a negative cutting coefficient (Ktc, Krc or Kac) or fits clearly worse than
    another (residual more than 1 / BETTER_RESIDUAL_RATIO times the best plausible one's);
    unchecked (no candidates) when the runs cannot be fitted at all."""
    out: AxesCheck = {"axes": axes.text, "candidates": [], "warnings": [],
                           "refusal": None, "checked": False}  # fmt: skip
    cands = _candidates(averages, tool, axes) if averages else None
    if not cands:
        return out
    out["candidates"], out["checked"] = cands, True
    given = cands[0]
    ranked = [c for c in _ranked(cands) if c is not given]
    best = ranked[0] if ranked else None
    runner = ranked[1] if len(ranked) > 1 else None
    better = (f"the runs fit {_describe(best)}" if best
              else "no mapping gives positive Ktc, Krc, Kac")  # fmt: skip
    if best and runner and not _tells(best, runner):
        alike = [c for c in ranked if not _tells(best, c)]
        better += (f" and {_describe(runner)} alike ({len(alike)} mappings with positive Ktc, "
                   "Krc, Kac fit alike: the runs cannot tell them apart)")  # fmt: skip
    msg = None
    if not given["plausible"]:
        neg = [k for k in CUTTING if given["coefficients"][k] <= 0]
        msg = (f"axes {axes.text} give a negative cutting coefficient ({', '.join(neg)}), so a "
               f"force axis is swapped or of the wrong sign; under {_describe(given)}; {better}; "
               "give --axes (x feed, y cross-feed, z tool axis up from the workpiece; forces on "
               "the workpiece)")  # fmt: skip
    elif best and best["residual_rms_n"] < BETTER_RESIDUAL_RATIO * given["residual_rms_n"]:
        msg = (f"axes {axes.text} fit clearly worse than another mapping: under "
               f"{_describe(given)}; {better}; give --axes")  # fmt: skip
    elif given["coefficients"]["Krc"] > given["coefficients"]["Ktc"]:
        # Slots cannot tell x = F1, y = F2 from x = -F2, y = F1 (same residual, K_tc and K_rc
        # trade places); K_rc above K_tc is unusual for metal cutting, so say which is which.
        twin = [c for c in ranked if c["coefficients"]["Ktc"] > c["coefficients"]["Krc"]
                and c["residual_rms_n"] <= 1.05 * given["residual_rms_n"]]  # fmt: skip
        if twin:
            out["warnings"].append(
                f"axes {axes.text} give Krc > Ktc (unusual: Krc/Ktc is mostly 0.2-0.7 in metal "
                f"cutting) and the runs fit another mapping as well: under {_describe(given)}; "
                f"under {_describe(twin[0])}; check --axes"
            )
    if msg:
        if refuse:
            out["refusal"] = msg
        else:
            out["warnings"].append(msg)
    return out


def choose_axes(
    averages: Sequence[RunAverage], tool: EndMill, base: AxisMap
) -> tuple[AxisMap, AxesChoice]:
    """``--axes auto``: the signed permutation of ``base`` whose fit gives positive cutting
    coefficients with the smallest residual, when the runs tell it from the runner-up (its
    residual at least 1 / BETTER_RESIDUAL_RATIO times larger). Returns (mapping, {"axes",
    "chosen", "runner_up", "candidates", "line"}); raises AnalysisError (one line) when the runs
    cannot be fitted, no mapping gives positive coefficients, or the runs cannot tell."""
    cands = _candidates(averages, tool, base) if averages else None
    if not cands:
        raise AnalysisError(
            f"--axes auto: {len(averages)} run(s) cannot be fitted under any mapping (too few "
            "runs or feeds); give --axes x=COLUMN,y=COLUMN,z=COLUMN"
        )
    ranked = _ranked(cands)
    if not ranked:
        raise AnalysisError(
            "--axes auto: none of the 48 signed permutations of the force columns gives positive "
            "Ktc, Krc and Kac: check the conditions (mode, widths, feeds) and the tool; or give "
            "--axes x=COLUMN,y=COLUMN,z=COLUMN"
        )
    best = ranked[0]
    runner = ranked[1] if len(ranked) > 1 else None
    if not _tells(best, runner):
        assert runner is not None
        raise AnalysisError(
            f"--axes auto: the runs cannot tell {_describe(best)} from {_describe(runner)} "
            "(slots alone cannot tell x from y: add a partial-immersion up- or down-milling "
            "cut); give --axes x=COLUMN,y=COLUMN,z=COLUMN (x feed, y cross-feed, z tool axis)"
        )
    line = f"auto: {_describe(best)}"
    if runner:
        ratio = runner["residual_rms_n"] / max(best["residual_rms_n"], 1e-300)
        line += f"; runner-up {_describe(runner)} ({ratio:.3g} x the residual)"
    chosen = parse_axes(best["axes"], "--axes auto")
    return chosen, {"axes": best["axes"], "chosen": best, "runner_up": runner,
                    "candidates": cands, "line": line}  # fmt: skip
