"""Fast path against per-block path: the comparison the fast-path tests share."""

from __future__ import annotations

from dataclasses import fields

from planning.nc.errors import NCError
from planning.nc.interpreter import Interpreter
from planning.nc.motion import Motion


def same_motion(a: Motion, b: Motion) -> None:
    for f in fields(Motion):
        x, y = getattr(a, f.name), getattr(b, f.name)
        assert x.dtype == y.dtype and x.shape == y.shape, f.name
        assert x.tobytes() == y.tobytes(), f.name


def outcome(lines: list[str], fast: bool, chunk: int | None = None, **options):
    it = Interpreter(file="p.ngc", fast=fast, **options)
    try:
        if chunk is None:
            motion = it.run(lines)
        else:
            motion = Motion.concatenate(list(it.iter_chunks(lines, chunk_blocks=chunk)))
    except NCError as exc:
        return ("error", str(exc), exc.line, exc.column, it.state), it
    return ("ok", motion, it.state), it


def check_fast_is_slow(lines: list[str], chunk: int | None = None, **options) -> None:
    fast, it_fast = outcome(lines, True, chunk, **options)
    slow, it_slow = outcome(lines, False, chunk, **options)
    assert fast[0] == slow[0], (fast[:2], slow[:2])
    if fast[0] == "ok":
        same_motion(fast[1], slow[1])
    else:
        assert fast[1:4] == slow[1:4]
    assert repr(fast[-1]) == repr(slow[-1])  # the whole modal state
    assert [repr(w) for w in it_fast.warnings] == [repr(w) for w in it_slow.warnings]
    assert it_fast.blocks_seen == it_slow.blocks_seen
