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
@pytest.mark.parametrize("chunk", [1, 13, 500, 65536])
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
