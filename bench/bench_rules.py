"""Feed rules: how fast a rule maps loads to feeds, a sweep is judged, and the rule base answers.

Prints: loads/s through FeedRule.feed_for (the post-processor's hot path), seconds to find the base
feed of a 10-run feed sweep (1 s of 10 kHz force each), rule-base lookups/s (exact and nearest)
over 1,000 groups. Figures only; nothing is asserted.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from _rules_sweep import sweep  # noqa: E402

from analysis.rules.basefeed import find_base_feed  # noqa: E402
from analysis.rules.load import slot_load_percent  # noqa: E402
from analysis.rules.rule import derive_rule  # noqa: E402
from analysis.rules.rulebase import GroupKey, RuleBase  # noqa: E402


def best(fn, n: int = 5) -> float:
    times = []
    for _ in range(n):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def main() -> None:
    rule = derive_rule("bench", 100, 1000, 3500, slot_load_percent("ball", 30, 0.3, 30))
    loads = np.random.default_rng(0).lognormal(-2, 1, 10_000_000)
    t = best(lambda: rule.feed_for(loads), 3)
    print(f"feed_for: {len(loads):,} loads in {t:.3f} s = {len(loads) / t / 1e6:.1f} M loads/s")

    runs = sweep(1000.0)
    t = best(lambda: find_base_feed(runs), 3)
    print(f"find_base_feed: 10 runs x 10,000 samples in {t * 1e3:.1f} ms")

    with tempfile.TemporaryDirectory() as d:
        rb = RuleBase(Path(d) / "rb.sqlite")
        t0 = time.perf_counter()
        keys = []
        for i in range(1000):
            k = GroupKey(
                f"family-{i % 7}",
                ("roughing", "pencil", "rest")[i % 3],
                10 + i % 40,
                30,
                ("fc30", "gm241")[i % 2],
                1000 + i,
                0.5,
                0.05,
            )
            rb.add(k, rule)
            keys.append(k)
        t_add = time.perf_counter() - t0
        print(
            f"rule base: 1,000 groups added in {t_add:.2f} s ({1000 / t_add:.0f} adds/s, "
            "one transaction each)"
        )
        t = best(lambda: [rb.lookup(k) for k in keys[:200]], 3)
        print(f"rule base: exact lookup {200 / t:.0f} /s")
        near = [
            GroupKey(
                k.part_family,
                k.operation,
                k.tool_diameter_mm + 0.5,
                30,
                k.material,
                k.spindle_rpm,
                0.5,
                0.05,
            )
            for k in keys[:200]
        ]
        t = best(lambda: [rb.lookup(k) for k in near], 3)
        print(f"rule base: nearest-match lookup {200 / t:.0f} /s")
        rb.close()


if __name__ == "__main__":
    main()
