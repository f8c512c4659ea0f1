"""analysis.runs.file: the loader's errors, device-index bookkeeping, windows, layout contract."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.runs import file as rf
from rig.daq import DaqInfo
from rig.log import RunWriter


def _info(rate_hz: float = 1000.0, block: int = 250) -> DaqInfo:
    return DaqInfo(
        device="t",
        physical_channels=("t/ai0", "t/ai1"),
        channel_names=("a", "b"),
        rate_hz=rate_hz,
        sample_format="volts_float64",
        input_range_v=10.0,
        block_samples=block,
    )


def _write(path: Path, blocks: list[tuple[int, int]], t0_s: float = 2.0) -> None:
    info = _info()
    with RunWriter(path, info, flush_interval_s=0.1) as w:
        w.on_start(info, t0_s)
        for first, n in blocks:
            w.on_block(first, np.vstack([first + np.arange(n), -(first + np.arange(n))]))


@pytest.fixture
def good_run(tmp_path: Path) -> Path:
    p = tmp_path / "good.h5"
    _write(p, [(0, 250), (250, 250), (600, 250), (850, 150)])
    return p


def test_layout_contract(good_run: Path) -> None:
    """The paths and attributes the module docstring documents are what the writer produced."""
    with h5py.File(good_run, "r") as f:
        assert f.attrs[rf.ATTR_FORMAT] == rf.FORMAT_NAME
        assert int(f.attrs[rf.ATTR_FORMAT_VERSION]) == rf.FORMAT_VERSION
        ds = f[rf.VOLTS]
        assert ds.dtype == np.float64 and ds.shape == (900, 2) and ds.maxshape == (None, 2)
        assert ds.chunks is not None
        assert f[rf.FORCES].attrs["rate_hz"] == 1000.0
        assert list(f[rf.FORCES].attrs["channel_names"]) == ["a", "b"]
        assert f[rf.EVENTS].dtype == rf.EVENT_DTYPE and f[rf.BLOCKS].dtype == rf.BLOCK_DTYPE
        for name in rf.META_NAMES:
            assert f[rf.meta_path(name)].dtype == np.uint8
        assert f[rf.EVENTS].compression == "gzip"  # readable by any HDF5 tool (not lzf)


def test_window_and_metadata_only(good_run: Path) -> None:
    run = rf.load_run(good_run)
    assert run.samples_stored == 900 and run.samples_acquired == 1000 and run.samples_lost == 100
    np.testing.assert_array_equal(run.volts[:, 0], run.sample_index)  # value = device index
    np.testing.assert_allclose(run.time_s, 2.0 + run.sample_index / 1000.0)
    win = rf.load_run(good_run, start_s=0.4, stop_s=0.7)
    np.testing.assert_array_equal(win.sample_index, np.r_[400:500, 600:700])
    np.testing.assert_array_equal(win.volts[:, 1], -win.sample_index)
    meta = rf.load_run(good_run, samples=False)
    assert meta.volts.shape == (0, 2) and meta.samples_stored == 900
    assert meta.duration_s == pytest.approx(1.0)


@settings(max_examples=80, deadline=None)
@given(st.lists(st.tuples(st.integers(1, 50), st.integers(0, 30)), min_size=1, max_size=12))
def test_device_index_from_loss_events(pieces: list[tuple[int, int]]) -> None:
    """Stored runs of samples separated by holes: the index rebuilt from events matches."""
    truth, rows, dev = [], [], 0
    for i, (n, hole) in enumerate(pieces):
        if hole and i > 0:
            rows.append((dev, hole, 0.0, 0.0, b"gap" if i % 2 else b"queue_full", b""))
            dev += hole
        truth.extend(range(dev, dev + n))
        dev += n
    rows.append((3, 0, 0.0, 0.0, b"overflow", b""))  # lost=0 events do not shift anything
    ev = np.array(rows, dtype=rf.EVENT_DTYPE)
    np.testing.assert_array_equal(rf.stored_to_device_index(len(truth), ev), truth)
    np.testing.assert_array_equal(rf.stored_to_device_index(len(truth), ev, start=3), truth[3:])
    for d in range(dev + 2):  # window bounds: first stored sample at device index >= d
        assert rf.device_to_stored_index(d, len(truth), ev) == np.searchsorted(truth, d)


def test_not_hdf5(tmp_path: Path) -> None:
    p = tmp_path / "notes.h5"
    p.write_text("Fx,Fy,Fz\n1,2,3\n")
    with pytest.raises(rf.RunFileError, match=r"notes.h5: not an HDF5 file \(starts with b'Fx,Fy"):
        rf.load_run(p)
    empty = tmp_path / "empty.h5"
    empty.write_bytes(b"")
    with pytest.raises(rf.RunFileError, match="not an HDF5 file.*empty file"):
        rf.load_run(empty)
    with pytest.raises(rf.RunFileError, match="run file not found"):
        rf.load_run(tmp_path / "missing.h5")
    with pytest.raises(rf.RunFileError, match="is a folder"):
        rf.load_run(tmp_path)


def test_foreign_hdf5(tmp_path: Path) -> None:
    p = tmp_path / "other.h5"
    with h5py.File(p, "w") as f:
        f["measurement/data"] = np.zeros(10)
    with pytest.raises(rf.RunFileError, match="HDF5 file of another program.*holds measurement"):
        rf.load_run(p)


def test_newer_format_version(good_run: Path) -> None:
    with h5py.File(good_run, "r+") as f:
        f.attrs[rf.ATTR_FORMAT_VERSION] = rf.FORMAT_VERSION + 1
    with pytest.raises(rf.RunFileError, match="newer than this cutlab reads"):
        rf.load_run(good_run)


@pytest.mark.parametrize("frac", [0.02, 0.5, 0.95])
def test_truncated(good_run: Path, tmp_path: Path, frac: float) -> None:
    data = good_run.read_bytes()
    p = tmp_path / "cut.h5"
    p.write_bytes(data[: int(len(data) * frac)])
    with pytest.raises(
        rf.RunFileError, match=rf"truncated HDF5 file: \d+ bytes of the {len(data)}"
    ):
        rf.load_run(p)


def test_cli_reports_bad_files_in_one_line(tmp_path: Path, capsys) -> None:
    from rig.cli import main

    p = tmp_path / "x.h5"
    p.write_text("hello")
    assert main(["data", "info", str(p)]) == 2
    err = capsys.readouterr().err
    assert err.strip().startswith("cutlab: error:") and "not an HDF5 file" in err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_iter_forces_gives_the_loaders_windows(tmp_path: Path) -> None:
    """Windows streamed with the file opened once are the loader's windows, number for number,
    across holes (device samples 500-599 and 750-849 lost) and past the end."""
    from analysis.config import load_rig
    from rig.daq import Calibration

    rig = load_rig()
    info = DaqInfo(device="t", physical_channels=("t/ai0", "t/ai1", "t/ai2"),
                   channel_names=tuple(c.name for c in rig.dynamometer.channels),
                   rate_hz=1000.0, sample_format="volts_float64", input_range_v=10.0,
                   block_samples=250)  # fmt: skip
    p = tmp_path / "cal.h5"
    with RunWriter(p, info, Calibration.from_rig(rig), flush_interval_s=0.1) as w:
        w.on_start(info, 2.0)
        for first, n in [(0, 250), (250, 250), (600, 150), (850, 150)]:
            idx = first + np.arange(n)
            w.on_block(first, np.vstack([idx, -idx, 0.5 * idx]) * 1e-3)
    meta = rf.load_run(p, samples=False)
    windows = [(0, 300), (300, 700), (700, 1000), (950, 1200), (1200, 1300)]
    for (a, b), (idx, force) in zip(windows, rf.iter_forces(p, windows, meta), strict=True):
        want = rf.load_run(p, (a - 0.5) / 1000.0, (b - 0.5) / 1000.0)
        np.testing.assert_array_equal(idx, want.sample_index)
        np.testing.assert_array_equal(force, want.force_n)
    assert len(next(rf.iter_forces(p, [(500, 600)], meta))[0]) == 0  # all lost
