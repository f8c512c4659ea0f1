"""Benchmark: the campaign's live chatter interlock against the whole-run detector, side by side.

The cuts and the truth are bench/bench_chatter_detect.py's (the regenerative twin, 2-4 teeth,
slot, half and quarter immersion up and down, 0.5-1.5 x the semi-discretization limit; truth from
the twin's true force, never from the detector's features). Each cut starts in the block at full
depth, cuts 1 s, leaves the block (the force ramps down over the cutter's radius) and runs on in
air. Three verdicts per cut:

- whole run: ``analysis.chatter.detect_chatter`` on the whole record (the report's verdict);
- live, before: ``indicators`` on the last 10 revolutions after every 0.1 s DAQ read, flagged on
  the first chattering window (the interlock as it was);
- live, now: :class:`rig.campaign.chatter_watch.ChatterWatch` itself, fed 0.1 s reads as the
  campaign's DAQ delivers them.

Prints false positives on stable cuts (and how many at a tooth-passing harmonic), missed chatter
beyond 1.1 x the limit and over all chattering cuts, and the live verdicts' latency: revolutions
and ms from the start of the cut to the read that stopped it (the twin's chatter grows from the
entry, so this bounds the latency from onset from above).

    .venv/bin/python bench/bench_chatter_live.py [--half cal|held|both] [--cache DIR]
"""

from __future__ import annotations

import argparse
import math
import pickle
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_chatter_detect import (  # noqa: E402
    RATE_HZ,
    Cut,
    near_tooth_harmonic,
    plan,
    simulate,
    truth,
)

from analysis.chatter import detect_chatter, indicators  # noqa: E402
from rig.campaign.chatter_watch import ChatterWatch  # noqa: E402

READ_S = 0.1  # the rig's DAQ read interval (configs/rig.toml read_interval_s)
BEFORE_REVS = 10  # the interlock's former window
FLOOR_N = 10.0  # the campaign's chatter_floor_n default


@dataclass(frozen=True)
class Verdict:
    chatter: bool
    frequency_hz: float
    at_s: float = math.nan  # end of the read that stopped the cut (live verdicts)


@dataclass(frozen=True)
class Case:
    cut: Cut
    truth: str  # stable, marginal, chatter, flip (bench_chatter_detect.truth)
    whole: Verdict
    before: Verdict
    now: Verdict


def cases(half: str, cache: Path | None) -> list[tuple[Cut, str, np.ndarray]]:
    """(cut, truth, measured Fx Fy N) of every cut of ``half``; simulated once per cache."""
    path = cache / f"live-{half}.pkl" if cache is not None else None
    if path is not None and path.exists():
        return pickle.loads(path.read_bytes())
    out = []
    for cut in plan(half):
        f_true, f_meas, exit_s = simulate(cut)
        says, _, visible = truth(f_true, cut.rpm * (1 + cut.speed_error), cut.teeth, exit_s)
        out.append((cut, "flip" if says == "chatter" and not visible else says, f_meas))
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(pickle.dumps(out))
    return out


def live_before(cut: Cut, f_meas: np.ndarray) -> Verdict:
    """The former interlock: ``indicators`` on the last 10 revolutions after every read."""
    n_win = int(math.ceil(BEFORE_REVS * 60.0 * RATE_HZ / cut.rpm))
    step = int(READ_S * RATE_HZ)
    for end in range(step, len(f_meas) + 1, step):
        if end < n_win:
            continue
        v = indicators(f_meas[end - n_win : end], RATE_HZ, cut.rpm, floor_n=FLOOR_N)
        if v.chatter:
            return Verdict(True, v.frequency_hz, end / RATE_HZ)
    return Verdict(False, math.nan)


def live_now(cut: Cut, f_meas: np.ndarray) -> Verdict:
    """The campaign's ChatterWatch, fed one DAQ read at a time."""
    watch = ChatterWatch(("Fx", "Fy"), RATE_HZ, cut.rpm, FLOOR_N)
    step = int(READ_S * RATE_HZ)
    for end in range(step, len(f_meas) + 1, step):
        if watch.push(f_meas[end - step : end]) is not None:
            return Verdict(True, watch.last.frequency_hz, end / RATE_HZ)
    return Verdict(False, math.nan)


def judge(cut: Cut, says: str, f_meas: np.ndarray) -> Case:
    r = detect_chatter(f_meas, RATE_HZ, cut.rpm)
    return Case(cut, says, Verdict(r.chatter, r.frequency_hz), live_before(cut, f_meas),
                live_now(cut, f_meas))  # fmt: skip


def rates(judged: list[Case], kind: str) -> dict[str, float]:
    """FP on stable cuts (at a tooth harmonic), missed beyond 1.1 x and over all chatter, and
    the latency (median and largest, revolutions and ms) of the chattering cuts caught."""
    v = [getattr(c, kind) for c in judged]
    stable = [i for i, c in enumerate(judged) if c.truth == "stable"]
    chat = [i for i, c in enumerate(judged) if c.truth == "chatter"]
    beyond = [i for i in chat if judged[i].cut.factor > 1.1]
    fp = [i for i in stable if v[i].chatter]
    caught = [i for i in beyond if v[i].chatter]
    revs = [v[i].at_s * judged[i].cut.rpm / 60 for i in caught]
    ms = [1e3 * v[i].at_s for i in caught]
    return {
        "stable": len(stable), "fp": len(fp),
        "fp_at_tooth": sum(near_tooth_harmonic(v[i].frequency_hz, judged[i].cut) for i in fp),
        "beyond": len(beyond), "missed_beyond": len(beyond) - len(caught),
        "chatter": len(chat), "missed": sum(not v[i].chatter for i in chat),
        "lat_revs": float(np.median(revs)) if revs else math.nan,
        "lat_revs_max": max(revs, default=math.nan),
        "lat_ms": float(np.median(ms)) if ms else math.nan, "lat_ms_max": max(ms, default=math.nan),
    }  # fmt: skip


def _pct(a: int, b: int) -> str:
    return f"{a:3d}/{b:<3d} ({100 * a / b:5.1f} %)" if b else f"{a:3d}/{b:<3d} (  -  )"


def report(judged: list[Case], title: str) -> None:
    print(f"\n{title}")
    print(f"{'verdict':<40} {'FP on stable':<18} {'at tooth':>8}  {'missed >1.1x':<18} "
          f"{'missed all':<18} latency (stop read from cut start)")  # fmt: skip
    names = (("whole", "whole run (detect_chatter)"), ("before", "live before (10 revs)"),
             ("now", f"live now ({ChatterWatch.describe()})"))  # fmt: skip
    for kind, name in names:
        r = rates(judged, kind)
        lat = "-" if kind == "whole" else (
            f"median {r['lat_revs']:.0f} revs / {r['lat_ms']:.0f} ms, "
            f"max {r['lat_revs_max']:.0f} revs / {r['lat_ms_max']:.0f} ms")  # fmt: skip
        print(
            f"{name:<40} {_pct(r['fp'], r['stable'])} {r['fp_at_tooth']:8d}  "
            f"{_pct(r['missed_beyond'], r['beyond'])} {_pct(r['missed'], r['chatter'])} {lat}"
        )
    for rpm in sorted({c.cut.rpm for c in judged}):
        w = ChatterWatch(("Fx", "Fy"), RATE_HZ, rpm, FLOOR_N)
        print(f"  at {rpm:6.0f} rpm the live watch needs {w.revolutions_needed} revolutions "
              f"of steady cut: {1e3 * w.revolutions_needed * 60 / rpm:.0f} ms (+ one read, "
              f"{1e3 * READ_S:.0f} ms)")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--half", choices=("cal", "held", "both"), default="held")
    ap.add_argument("--cache", type=Path, default=None, help="keep the simulated cuts here")
    args = ap.parse_args()
    for half in ("cal", "held") if args.half == "both" else (args.half,):
        t0 = time.perf_counter()
        judged = [judge(cut, says, f) for cut, says, f in cases(half, args.cache)]
        name = "calibration" if half == "cal" else "held-out"
        report(judged, f"{name} half ({len(judged)} cuts, {time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
