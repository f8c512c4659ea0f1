"""Streaming interpretation: Motion chunks, StreamStats, the chunked CSV table, bounded lines."""

from __future__ import annotations

import io
import math
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.config import load_machine
from planning.nc import interpret, interpret_file
from planning.nc.errors import NCError
from planning.nc.motion import Motion
from planning.nc.run import MAX_LINE_CHARS, file_lines, file_mentions_rotary, iter_motion_chunks
from planning.nc.stats import ExactSum, StreamStats, motion_stats
from planning.nc.table import write_motion_csv

ROOT = Path(__file__).resolve().parent.parent
PROGRAMS = sorted((ROOT / "data" / "programs").glob("*.nc"))
sys.path.insert(0, str(ROOT / "bench"))


def _generated(tmp_path: Path, n: int = 3000) -> Path:
    from bench_nc import write_program

    p = tmp_path / "gen.nc"
    write_program(p, n)
    return p


def _same(a, b) -> bool:
    da, db = a.to_dict(), b.to_dict()
    for k, va in da.items():
        vb = db[k]
        if isinstance(va, tuple):
            if not np.array_equal(np.asarray(va), np.asarray(vb), equal_nan=True):
                return False
        elif va != vb and not (isinstance(va, float) and math.isnan(va) and math.isnan(vb)):
            return False
    return True


@pytest.fixture(params=["shipped", "generated"])
def program(request, tmp_path) -> list[Path]:
    return PROGRAMS if request.param == "shipped" else [_generated(tmp_path)]


@pytest.mark.parametrize("chunk", [1, 7, 1000, 65536])
def test_chunks_concatenate_to_the_whole_motion(program, chunk) -> None:
    for path in program:
        whole = interpret_file(path)
        parts = list(iter_motion_chunks(path, chunk_blocks=chunk))
        assert all(len(p) for p in parts)
        assert Motion.concatenate(parts).equals(whole)


@pytest.mark.parametrize("machine", [None, "ace-h63", "lab-grbl", "mill-5axis"])
# one block a chunk: a minute or two each on the generated program (in CI's command, not in a
# plain `pytest`; 13 keeps small chunks in the quick tier)
@pytest.mark.parametrize("chunk", [pytest.param(1, marks=pytest.mark.long), 13, 500, 65536])
def test_stream_stats_equal_motion_stats(program, machine, chunk) -> None:
    cfg = load_machine(machine) if machine else None
    for path in program:
        whole = motion_stats(interpret_file(path, cfg, strict=False), cfg)
        acc = StreamStats(cfg)
        for part in iter_motion_chunks(path, cfg, strict=False, chunk_blocks=chunk):
            acc.add(part)
        assert _same(acc.result(), whole), (path, machine, chunk)
        if cfg is not None and cfg.accel_mm_s2 is not None:
            assert whole.accel_time_s > whole.time_s


def test_stream_stats_of_nothing() -> None:
    assert _same(StreamStats().result(), motion_stats(Motion.empty()))


def test_exact_sum_is_correctly_rounded_whatever_the_split() -> None:
    rng = np.random.default_rng(3)
    x = rng.standard_normal(20_000) * 10.0 ** rng.integers(-12, 12, 20_000)
    acc = ExactSum()
    for k in range(0, x.size, 777):
        acc.add(x[k : k + 777])
    assert acc.value() == math.fsum(x)


def test_csv_round_trips_every_float(program) -> None:
    for path in program:
        m = interpret_file(path)
        fh = io.StringIO()
        n = write_motion_csv(iter_motion_chunks(path, chunk_blocks=100), fh, rotary=True)
        assert n == len(m)
        fh.seek(0)
        df = pd.read_csv(fh)
        ref = m.to_dataframe()
        assert list(df.columns) == list(ref.columns)
        for col in ref.columns:
            a, b = df[col].to_numpy(), ref[col].to_numpy()
            if a.dtype.kind == "f":
                assert np.array_equal(a, b.astype(float), equal_nan=True), col
            else:
                assert (a == b).all(), col


def test_csv_keeps_digits_that_pct_g_drops() -> None:
    fh = io.StringIO()
    write_motion_csv([interpret("G1 X3554.8655 Y-0.1 F300\n")], fh)
    text = fh.getvalue()
    assert "3554.8655" in text and "rotary" not in text and ",a0" not in text.splitlines()[0]


def test_rotary_columns_only_when_the_program_has_abc_words(tmp_path) -> None:
    a = tmp_path / "a.nc"
    a.write_text("(ABC 1 comment)\nG1 X1 F100 ; B2\n")
    assert not file_mentions_rotary(a)
    a.write_text("G1 X1 F100\nG1 a 10\n")
    assert file_mentions_rotary(a)


def test_file_lines_line_ends(tmp_path) -> None:
    p = tmp_path / "e.nc"
    p.write_bytes(b"\xef\xbb\xbfG1 X1\nG2\r\nG3\rG4\rG5\nG6")
    assert list(file_lines(p)) == ["G1 X1\n", "G2\r\n", "G3", "G4", "G5", "G6"]


def test_a_line_too_long_is_refused_at_once(tmp_path) -> None:
    p = tmp_path / "one-line.nc"
    with open(p, "wb") as fh:
        fh.write(b"G1 X1 F100\n")
        fh.write(b"X1" * 2_000_000)  # 4 MB without a line end
    t = time.perf_counter()
    with pytest.raises(NCError) as err:
        list(file_lines(p))
    assert time.perf_counter() - t < 1.0
    msg = str(err.value)
    assert f"{p}:2" in msg and f"longer than {MAX_LINE_CHARS} characters" in msg
    q = tmp_path / "short.nc"
    q.write_text("G0 X1\n" + "(" + "c" * 100 + ")\n")
    with pytest.raises(NCError, match=r"short.nc:2:.*longer than 50 characters"):
        list(file_lines(q, max_line_chars=50))
    assert len(list(file_lines(q))) == 2


def test_chunk_size_must_be_positive() -> None:
    with pytest.raises(ValueError):
        list(iter_motion_chunks(["G0 X1"], chunk_blocks=0))


def _reference_rows(m: Motion, rotary: bool) -> str:
    """The CSV rows as the first writer made them: ``repr`` per float, '' for NaN."""
    from planning.nc.motion import KIND_NAMES

    def floats(a):
        return ["" if x != x else repr(x) for x in a.tolist()]

    def ints(a):
        return list(map(repr, a.tolist()))

    s, e, c = m.start, m.end, m.center
    cols = [
        ints(m.line), ints(m.block), [KIND_NAMES[k] for k in m.kind.tolist()],
        *[floats(a[:, i]) for a in (s, e, c) for i in range(3)],
        ints(m.plane), floats(m.feed_mm_min), floats(m.spindle_rpm), ints(m.tool),
        [str(bool(x)) for x in m.coolant.tolist()], floats(m.dwell_s),
    ]  # fmt: skip
    if rotary:
        cols += [floats(a[:, i]) for a in (m.rotary_start_deg, m.rotary_end_deg) for i in range(3)]
    return "".join(",".join(row) + "\n" for row in zip(*cols))


_HARD = [
    0.0, -0.0, math.nan, math.inf, -math.inf, 10.0, -10.0, 3554.8655, 274.9999, 0.1 + 0.2,
    25.4 * 0.1234, 25.4 * -3.0001, 1 / 25.4, 1e-4, 1e-5, 9.999999999999999e-05, 1e15, 1e16,
    9999999999999998.0, 123456789012345.67, 2.0**49, 2.0**50, 2.0**53, 5e-324, 1e308, -1e-300,
    4.440892098500626e-16, 1 / 3, 0.5, 0.05, 0.0005, 999999999999999.9, 12345.678901234567,
    12000.0, 1e22, 1.5e-7, -0.0001,
]  # fmt: skip


def _random_floats(rng, n: int) -> np.ndarray:
    kinds = rng.integers(0, 8, n)
    x = np.select(
        [kinds == 0, kinds == 1, kinds == 2, kinds == 3, kinds == 4, kinds == 5, kinds == 6],
        [
            np.round(rng.uniform(-500, 500, n), 4),
            np.round(rng.uniform(-20, 20, n), 4) * 25.4,
            rng.uniform(-1, 1, n) * 10.0 ** rng.integers(-25, 25, n),
            np.asarray(_HARD)[rng.integers(0, len(_HARD), n)],
            rng.integers(-1000, 1000, n).astype(float),
            rng.integers(0, 2**63, n, dtype=np.uint64).view(np.float64),  # any bits
            np.round(rng.uniform(-1, 1, n), 3) / 10.0 ** rng.integers(0, 6, n),
        ],
        default=rng.uniform(-1000, 1000, n),
    )
    return x


def _random_motion(rng, n: int) -> Motion:
    """Rows like a program's (a start is mostly the end before it, runs of equal values) with
    values that are hard to write."""
    end = _random_floats(rng, 3 * n).reshape(n, 3)
    end[rng.random((n, 3)) < 0.3] = 0.0  # runs of one value
    start = np.empty_like(end)
    start[1:] = end[:-1]
    start[0] = _random_floats(rng, 3)
    jump = rng.random(n) < 0.05
    start[jump] = _random_floats(rng, 3 * int(jump.sum())).reshape(-1, 3)

    def col(p_new: float) -> np.ndarray:
        v = _random_floats(rng, n)
        keep = rng.random(n) > p_new
        keep[0] = False
        idx = np.maximum.accumulate(np.where(keep, 0, np.arange(n)))
        return v[idx]  # runs

    rot_end = np.stack([col(0.3) for _ in range(3)], axis=1)
    rot_start = np.empty_like(rot_end)
    rot_start[1:] = rot_end[:-1]
    rot_start[0] = _random_floats(rng, 3)
    centre = np.stack([col(0.5) for _ in range(3)], axis=1)
    centre[rng.random(n) < 0.5] = np.nan
    line = np.cumsum(rng.integers(0, 3, n)).astype(np.int32) + int(rng.integers(0, 10**9))
    return Motion(
        kind=rng.integers(0, 5, n).astype(np.int8),
        start=start, end=end, center=centre,
        plane=rng.choice(np.array([17, 18, 19], np.int8), n),
        feed_mm_min=col(0.2), spindle_rpm=col(0.05),
        tool=np.where(rng.random(n) < 0.9, 1, rng.integers(-5, 100_000, n)).astype(np.int32),
        coolant=rng.random(n) < 0.5, line=line, block=(line - 1).astype(np.int32),
        dwell_s=col(0.1), rotary_start_deg=rot_start, rotary_end_deg=rot_end,
    )  # fmt: skip


@pytest.mark.long
@pytest.mark.parametrize("seed", range(6))
def test_csv_rows_equal_repr_of_every_value(seed) -> None:
    from planning.nc.table import ROWS_PER_WRITE, motion_rows

    rng = np.random.default_rng(seed)
    sizes = [1, 2, 3, 25, 100, 3000, ROWS_PER_WRITE + 77]
    chunks = [_random_motion(rng, int(k)) for k in sizes]
    for rotary in (False, True):
        for m in chunks:
            assert motion_rows(m, rotary) == _reference_rows(m, rotary)
        fh = io.StringIO()
        assert write_motion_csv(chunks, fh, rotary=rotary) == sum(sizes)
        lines = fh.getvalue().splitlines(keepends=True)
        assert "".join(lines[1:]) == "".join(_reference_rows(m, rotary) for m in chunks)
    assert motion_rows(Motion.empty(), False) == ""


@pytest.mark.long
def test_csv_floats_as_repr_writes_them() -> None:
    from planning.nc.table import _float_text

    rng = np.random.default_rng(11)
    v = np.concatenate([np.asarray(_HARD * 3), _random_floats(rng, 100_000)])
    with np.errstate(invalid="ignore"):
        v = np.concatenate([v, np.nextafter(v, np.inf), np.nextafter(v, -np.inf), -v])
    for part in (v, v[:5], v[:40], v[np.isfinite(v)]):
        text = [row.tobytes().replace(b"\0", b"").decode() for row in _float_text(part)]
        assert text == ["" if x != x else repr(x) for x in part.tolist()]
