"""`flowkit info` and `flowkit demo` through the real CLI entry point, and the committed
heated-room dataset (tested unconditionally: it is the built-in demo data)."""

from pathlib import Path

import h5py
import numpy as np
import pytest

from flowkit.cli import main
from flowkit.datasets import hotroom, hotroom_path, hotroom_times

DATA = Path(__file__).parent / "data"
SHARED = Path(__file__).parents[1] / ".." / "shared" / "datasets" / "hotroom"


def run(capsys, *argv):
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


def test_info_on_a_vtk_file(capsys):
    rc, out, _ = run(capsys, "info", str(DATA / "rect_appended_raw_zlib.vtr"), "--stats")
    assert rc == 0
    assert "grid: rectilinear, shape (4, 3, 5) (60 nodes)" in out
    assert "x: [0, 0.9], spacing 0.1..0.55" in out and "time: 1.5" in out
    assert "U: vector (3), float64, 1.44 kB, |U| in [" in out
    assert "T: scalar, float32, 240 B, range [0, 18.9]" in out
    assert "cell data not loaded" in out and "--stats)" not in out


def test_info_reports_nan_and_inf_counts(tmp_path, capsys):
    x = np.arange(3.0)
    U = np.ones((3, 3, 3, 3))
    U[0, 0, 0] = np.nan
    T = np.zeros((3, 3, 3))
    T[1, 1, 1] = np.inf
    np.savez(tmp_path / "n.npz", x=x, y=x, z=x, U=U, T=T)
    rc, out, _ = run(capsys, "info", str(tmp_path / "n.npz"), "--stats")
    assert rc == 0 and "|U| in [1.73205, 1.73205]" in out and "3 NaN" in out and "1 inf" in out


def test_info_on_the_hotroom_series_lists_snapshots(capsys):
    rc, out, _ = run(capsys, "info", str(hotroom_path()), "--time", "1200", "--stats")
    assert rc == 0
    assert "5 snapshot(s)" in out and "[4] t = 2000" in out
    assert "time: 1200" in out and "grid: uniform, shape (41, 21, 41)" in out
    assert "spacing 0.25" in out and "T [K]: scalar, float32, 141 kB, chunks 11x11x21, range [300, 600]" in out


def test_info_reads_no_array_data_without_stats(tmp_path, capsys, monkeypatch):
    """Without --stats, info prints types, sizes and chunking from the metadata alone: no
    slab of any array is read (every read of array data goes through Source.fill)."""
    from flowkit.fields import stored

    reads = []
    monkeypatch.setattr(stored.Source, "fill", lambda *a: reads.append(a))
    for cls in (stored.InMemory, stored.Stacked, stored.Flipped):
        monkeypatch.setattr(cls, "fill", lambda *a: reads.append(a))
    from flowkit.fields.readers import hdf5

    monkeypatch.setattr(hdf5.H5Source, "fill", lambda *a: reads.append(a))
    rc, out, _ = run(capsys, "info", str(hotroom_path()))
    assert rc == 0 and not reads
    assert "U [m/s]: vector (3), float32" in out and "chunks" in out and "range [" not in out
    assert "--stats)" in out
    rc, out, _ = run(capsys, "info", str(hotroom_path()), "--stats")
    assert rc == 0 and reads and "range [" in out


def test_info_errors_are_one_line_naming_the_file(tmp_path, capsys):
    rc, _, err = run(capsys, "info", str(tmp_path / "gone.vti"))
    assert rc == 2 and err.strip().endswith("gone.vti: no such file") and err.count("\n") == 1
    rc, _, err = run(capsys, "info", str(DATA / "image_binary.vti"), "--vector", "W")
    assert rc == 2 and "no vector 'W'" in err and "vectors in the file: U" in err
    (tmp_path / "cut.vti").write_bytes((DATA / "image_binary.vti").read_bytes()[:900])
    rc, _, err = run(capsys, "info", str(tmp_path / "cut.vti"))
    assert rc == 2 and "cut.vti: VTK file is truncated or corrupt" in err and "Traceback" not in err


def test_info_on_a_lines_file(tmp_path, capsys):
    from flowkit.io.lines_h5 import write_lines
    from flowkit.lines import Lines

    path = write_lines(Lines(np.zeros((2, 3)) + [[0, 0, 0], [1, 0, 0]], [0, 2]), tmp_path / "l.h5")
    rc, out, _ = run(capsys, "info", str(path))
    assert rc == 0 and out.startswith(f"{path}: flowkit lines file") and "lines: 1" in out


@pytest.mark.skipif(not SHARED.is_dir(), reason=f"{SHARED} absent (shared data beside the clone)")
def test_info_on_a_vtu_glob(capsys):
    rc, out, _ = run(capsys, "info", str(SHARED / "hotroom_t*.vtu"), "--snapshot", "-1")
    assert rc == 0 and "[0] t = 400" in out and "time: 2000" in out
    assert "lattice rebuilt exactly" in out


def test_demo_prints_the_heated_room_and_writes_its_outputs(capsys, tmp_path):
    rc, out, _ = run(capsys, "demo", "--out", str(tmp_path))
    assert rc == 0 and "hotroom.h5[snapshot 4]" in out and "time: 2000" in out
    assert "U [m/s]: vector (3)" in out and "p [m2/s2]: scalar" in out
    written = [line.split(" ", 1)[1] for line in out.splitlines() if line.startswith("wrote ")]
    assert any(w.endswith(".h5") for w in written) and any(w.endswith(".png") for w in written)
    assert all(Path(w).is_file() and Path(w).is_relative_to(tmp_path) for w in written)


# -- the committed dataset -------------------------------------------------------------------
def test_hotroom_dataset():
    path = hotroom_path()
    assert path.stat().st_size < 4e6
    assert hotroom_times() == [400.0, 800.0, 1200.0, 1600.0, 2000.0]
    f = hotroom()
    assert f.time == 2000 and f.grid.uniform and f.grid.shape == (41, 21, 41)
    np.testing.assert_array_equal(f.grid.bounds, [[0, 10], [0, 5], [0, 10]])
    assert set(f.scalars) == {"T", "p"}
    T = f.scalars["T"]
    assert T.min() == 300 and T.max() == 600 and np.isfinite(f.vector).all()
    assert 0.2 < np.abs(f.vector).max() < 0.4  # |U| up to about 0.3 m/s
    with h5py.File(path) as h:
        ds = h["snapshots/0000/vectors/U"]
        assert ds.dtype == np.float32 and ds.compression == "gzip" and ds.shuffle
        assert "hotRoom" in h.attrs["title"]
    assert not np.array_equal(hotroom(snapshot=0).vector, f.vector)  # the snapshots differ


@pytest.mark.skipif(not SHARED.is_dir(), reason=f"{SHARED} absent (shared data beside the clone)")
def test_hotroom_dataset_matches_the_openfoam_export():
    from flowkit.fields.readers import load_field

    for t in (400, 2000):
        src = load_field(SHARED / f"hotroom_t{t:04d}.vtu")
        f = hotroom(time=t)
        assert f.grid == src.grid
        np.testing.assert_array_equal(f.vector, src.vector)
        for n in ("T", "p"):
            np.testing.assert_array_equal(f.scalars[n], src.scalars[n])
