"""Unstructured meshes (.vtu, .vtm) read and resampled by cell location, on small meshes the
tests write (tests/meshes.py): every cell kind reproduces a linear field exactly, nodes in no
cell are NaN (a cubic hole), every encoding reads the same, bad cells are named."""

from __future__ import annotations

import json

import numpy as np
import pytest
from meshes import (
    HEX,
    POLY,
    PYRAMID,
    TET,
    VOXEL,
    WEDGE,
    block,
    cube_faces,
    linear_t,
    linear_u,
    write_vtu,
)

from flowkit.cli import main
from flowkit.fields import Grid, ReaderError, load_field
from flowkit.fields import resample as rs
from flowkit.fields.mesh import MeshError
from flowkit.fields.resample import locate


def grid_in(lo, hi, n):
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return Grid.regular(lo, (hi - lo) / (np.array(n) - 1), n)


def check_linear(f, atol=1e-12):
    """Finite nodes hold the linear fields exactly; returns the mask of NaN nodes."""
    P = f.grid.node_points()
    nan = np.isnan(f.vector[..., 0])
    np.testing.assert_allclose(f.vector[~nan], linear_u(P[~nan]), rtol=0, atol=atol)
    np.testing.assert_allclose(f.scalars["T"][~nan], linear_t(P[~nan]), rtol=0, atol=1e-5)
    assert np.array_equal(np.isnan(f.scalars["T"]), nan)
    return nan


# -- every cell kind, distorted (no cell is affine), against a linear field -------------------
RNG = np.random.default_rng(7)


def distorted(points, amount=0.12):
    return points + RNG.uniform(-amount, amount, points.shape)


SINGLE = {
    "tet": ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [(TET, [0, 1, 2, 3])]),
    "pyramid": ([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1]],
                [(PYRAMID, [0, 1, 2, 3, 4])]),
    "wedge": ([[0, 0, 0], [0, 1, 0], [1, 0, 0], [0, 0, 1], [0, 1, 1], [1, 0, 1]],
              [(WEDGE, [0, 1, 2, 3, 4, 5])]),
    "hex": (np.stack(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij"), -1).reshape(-1, 3)[
        [0, 4, 6, 2, 1, 5, 7, 3]], [(HEX, list(range(8)))]),
    "voxel": (np.stack(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij"), -1).reshape(-1, 3)[
        [0, 4, 2, 6, 1, 5, 3, 7]], [(VOXEL, list(range(8)))]),
}


@pytest.mark.parametrize("kind", [*SINGLE, "poly"])
def test_each_cell_kind_reproduces_a_linear_field(tmp_path, kind):
    if kind == "poly":
        pts, cells = block((1, 1, 1), kinds="poly")
    else:
        pts, cells = SINGLE[kind]
    pts = np.asarray(pts, float)
    if kind != "voxel":  # (a voxel is axis-aligned by definition)
        pts = distorted(pts, 0.08)
    path = write_vtu(tmp_path / f"{kind}.vtu", pts, cells)
    f = load_field(path, resample=(9, 8, 7))
    nan = check_linear(f)
    assert f.time == 2.5
    assert 0 < nan.sum() < nan.size or kind in ("hex", "voxel", "poly")
    assert (~nan).sum() >= 8  # enough nodes inside to mean something
    assert "interpolated by the shape functions" in f.notes[0]
    assert f"{int(nan.sum())} of {nan.size} nodes lie in no cell" in f.notes[0]


def test_outside_of_each_kind_is_nan(tmp_path):
    # a node is finite exactly when it lies in the cell: tetrahedron and wedge half-spaces
    pts, cells = SINGLE["tet"]
    f = load_field(write_vtu(tmp_path / "t.vtu", np.asarray(pts, float), cells),
                   resample=(11, 11, 11))
    P = f.grid.node_points()
    inside = P.sum(-1) <= 1 + 1e-9
    assert np.array_equal(np.isfinite(f.vector[..., 0]), inside)
    pts, cells = SINGLE["wedge"]
    f = load_field(write_vtu(tmp_path / "w.vtu", np.asarray(pts, float), cells),
                   resample=(11, 11, 5))
    P = f.grid.node_points()
    assert np.array_equal(np.isfinite(f.vector[..., 0]), P[..., 0] + P[..., 1] <= 1 + 1e-9)


def test_mixed_mesh_with_polyhedra_and_a_cubic_hole(tmp_path):
    kinds = ["hex", "poly", "wedges", "pyramids", "tets"]
    pts, cells = block((5, 5, 5), hole=((1, 1, 1), (4, 4, 4)),
                       kinds=lambda ijk: kinds[sum(ijk) % len(kinds)])
    assert {c[0] for c in cells} == {HEX, POLY, WEDGE, PYRAMID, TET}
    path = write_vtu(tmp_path / "mixed.vtu", pts, cells)
    f = load_field(path, resample=(21, 21, 21))  # spacing 0.25
    nan = check_linear(f)
    P = f.grid.node_points()
    in_hole = np.all((P > 1 + 1e-9) & (P < 4 - 1e-9), axis=-1)
    assert np.array_equal(nan, in_hole)  # the hole's interior and nothing else
    assert in_hole.sum() == 11 ** 3
    assert f"{11 ** 3} of {21 ** 3} nodes lie in no cell" in f.notes[0]
    assert "polyhedra split into" in f.notes[0] and "polyhedron" in f.notes[0]


def test_opening_locates_nothing_until_an_array_is_read(tmp_path, monkeypatch, capsys):
    pts, cells = block((4, 4, 4), hole=((1, 1, 1), (3, 3, 3)), kinds="poly")
    path = write_vtu(tmp_path / "m.vtu", pts, cells)
    calls = []
    monkeypatch.setattr(rs, "locate", lambda *a: calls.append(1) or locate(*a))
    f = load_field(path, resample=(9, 9, 9))
    assert f.grid.shape == (9, 9, 9) and not calls
    assert "not located yet" in f.notes[0] and "lie in no cell" not in f.notes[0]
    assert main(["info", str(path), "--resample", "9,9,9"]) == 0
    out = capsys.readouterr().out
    assert "not located yet" in out and not calls
    assert main(["info", str(path), "--resample", "9,9,9", "--stats"]) == 0
    out = capsys.readouterr().out
    assert f"{3 ** 3} of {9 ** 3} nodes lie in no cell" in out and "not located" not in out
    nan = np.isnan(f.vector[..., 0])  # located once, for every array of the field
    f.scalars["T"]
    assert len(calls) == 2 and nan.sum() == 3 ** 3  # (one for info --stats, one here)
    assert f"{3 ** 3} of {9 ** 3} nodes lie in no cell" in f.notes[0]
    assert "polyhedra split into" in f.notes[0]


def test_lines_end_at_the_hole(tmp_path):
    from flowkit import trace
    from flowkit.integrate.reasons import Reason

    pts, cells = block((5, 3, 3), hole=((2, 0, 0), (3, 3, 3)))  # a wall across x = 2..3
    u = np.zeros_like(pts)
    u[:, 0] = 1.0
    path = write_vtu(tmp_path / "wall.vtu", pts, cells, point_data={"U": u})
    f = load_field(path, resample="spacing:0.25")
    lines = trace(f, np.array([[0.1, 1.5, 1.5]]), max_length=10.0)
    assert lines.points[:, 0].max() <= 2.0 + 1e-9  # no vertex inside the solid
    assert lines.line_data["reason"][0] == Reason.NAN_FIELD


# -- encodings and layouts ----------------------------------------------------------------------
ENCODINGS = {
    "ascii": {"encoding": "ascii"},
    "binary": {"encoding": "binary", "header": "UInt32"},
    "binary_zlib": {"encoding": "binary", "compress": True},
    "appended_raw": {"encoding": "appended"},
    "appended_raw_zlib_u32": {"encoding": "appended", "compress": True, "header": "UInt32"},
    "appended_base64": {"encoding": "appended", "b64": True},
    "appended_base64_zlib": {"encoding": "appended", "b64": True, "compress": True},
    "pieces": {"encoding": "appended", "compress": True, "pieces": 3},
    "vtk94_polyhedra": {"encoding": "binary", "layout": "vtk94"},
}


@pytest.mark.parametrize("name", ENCODINGS)
def test_every_encoding_reads_the_same(tmp_path, name):
    pts, cells = block((2, 2, 2), kinds=lambda ijk: "poly" if sum(ijk) % 2 else "wedges")
    cell_u = np.arange(len(cells) * 3, dtype=float).reshape(-1, 3)
    opts = ENCODINGS[name]
    path = write_vtu(tmp_path / f"{name}.vtu", pts, cells, cell_data={"rho": cell_u[:, 0]},
                     **opts)
    f = load_field(path, resample=(5, 5, 5))
    assert not check_linear(f).any()  # the mesh fills its box
    np.testing.assert_allclose(f.grid.bounds, [[0, 2]] * 3)
    assert f.time == 2.5
    assert "cell data not loaded" in " ".join(f.notes)


# -- cell data, the grid, .vtm ----------------------------------------------------------------------
def test_cell_data_is_constant_per_cell(tmp_path):
    pts, cells = block((2, 1, 1))
    path = write_vtu(tmp_path / "c.vtu", pts + [0, 0.1, 0], cells,  # (no lattice: resampled)
                     cell_data={"U": [[1.0, 0, 0], [2.0, 0, 0]], "k": [5.0, 7.0]})
    f = load_field(path, data="cell", resample=(9, 2, 2))
    x = f.grid.x
    assert np.all(f.vector[x < 1 - 1e-9, ..., 0] == 1.0)
    assert np.all(f.vector[x > 1 + 1e-9, ..., 0] == 2.0)
    assert set(np.unique(f.scalars["k"])) == {5.0, 7.0}
    assert "constant per cell" in f.notes[0]


def test_automatic_grid_follows_the_fine_cells_under_a_cap(tmp_path, monkeypatch):
    pts, cells = block((8, 4, 4))
    pts = pts * [1.0, 0.5, 0.5]  # cells 1 x 0.5 x 0.5
    pts[:, 0] += 0.05 * pts[:, 1] ** 2  # bent: no longer a lattice, cells a little longer
    path = write_vtu(tmp_path / "a.vtu", pts, cells)
    f = load_field(path)
    boxes = np.array([np.ptp(pts[c], axis=0) for _, c in cells])
    h = np.percentile(np.cbrt(boxes.prod(1)), 10)
    assert f"spacing {h:.4g}: the 10th percentile of the cells' sizes" in f.notes[0]
    span = pts.max(0) - pts.min(0)
    assert f.grid.shape == tuple(np.round(span / h).astype(int) + 1)
    monkeypatch.setattr(rs, "AUTO_MAX_NODES", 200)
    g = load_field(path)
    assert np.prod(g.grid.shape) <= 200 and "coarsened" in g.notes[0]
    s = load_field(path, resample="spacing:0.25")
    np.testing.assert_allclose(s.grid.spacing, 0.25, rtol=0.02)


def test_a_lattice_of_nodes_is_kept_unless_resample_is_given(tmp_path):
    pts, cells = block((3, 2, 2))
    path = write_vtu(tmp_path / "l.vtu", pts, cells)
    f = load_field(path)
    assert f.grid.shape == (4, 3, 3) and "lattice rebuilt exactly" in f.notes[0]
    g = load_field(path, resample="7,5,5")
    assert g.grid.shape == (7, 5, 5) and not check_linear(g).any()


def write_vtm(folder, pts, cells, **data):
    """folder/case_5.vtm as foamToVTK writes it: its internal mesh and an inlet patch."""
    (folder / "case_5" / "boundary").mkdir(parents=True, exist_ok=True)
    write_vtu(folder / "case_5" / "internal.vtu", pts, cells, **data)
    (folder / "case_5" / "boundary" / "inlet.vtp").write_text("<VTKFile/>")
    (folder / "case_5.vtm").write_text(
        "<?xml version='1.0'?>\n<VTKFile type='vtkMultiBlockDataSet' version='1.0'>"
        "<vtkMultiBlockDataSet><DataSet name='internal' file='case_5/internal.vtu' />"
        "<Block name='boundary'><DataSet name='inlet' file='case_5/boundary/inlet.vtp' />"
        "</Block></vtkMultiBlockDataSet></VTKFile>")
    return folder / "case_5.vtm"


def test_vtm_and_vtm_series_as_foamtovtk_writes_them(tmp_path):
    pts, cells = block((2, 2, 2), kinds="poly")
    write_vtm(tmp_path, pts, cells)
    (tmp_path / "case.vtm.series").write_text(json.dumps(
        {"file-series-version": "1.0", "files": [{"name": "case_5.vtm", "time": 5}]}))
    f = load_field(tmp_path / "case_5.vtm", resample=(5, 5, 5))
    assert not check_linear(f).any()
    g = load_field(tmp_path / "case.vtm.series", resample=(5, 5, 5))
    np.testing.assert_array_equal(g.vector, f.vector)
    with pytest.raises(ReaderError, match=r"case_5\.vtm: block 'boundary/inlet' is inlet\.vtp, a surface"):
        load_field(tmp_path / "case_5.vtm", block="boundary/inlet")
    with pytest.raises(ReaderError, match=r"no block 'wall'; blocks: internal, boundary/inlet"):
        load_field(tmp_path / "case_5.vtm", block="wall")


# -- bad input -------------------------------------------------------------------------------
def bad_meshes():
    cube = SINGLE["hex"][0].astype(float)
    flat = np.concatenate([cube, cube + [2, 0, 0]])
    flat[12:, 2] = 0.0  # the second cube's top pressed onto its bottom
    inverted = [4, 5, 6, 7, 0, 1, 2, 3]  # top listed first
    faces = cube_faces(list(range(8)))
    return {
        "inverted": (cube, [(HEX, list(range(8))), (HEX, inverted)],
                     r"cell 1 \(hexahedron\) is inverted"),
        "degenerate": (flat, [(HEX, list(range(8))), (HEX, list(range(8, 16)))],
                       r"cell 1 \(hexahedron\) is degenerate"),
        "open": (cube, [(HEX, list(range(8))), (POLY, faces[:5])],
                 r"cell 1 \(polyhedron\): .*open faces"),
        "wedge_inverted": (SINGLE["wedge"][0], [(WEDGE, [0, 2, 1, 3, 5, 4])],
                           r"cell 0 \(wedge\) is inverted"),
        "flat_tet": ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0, 0, 1]],
                     [(TET, [0, 1, 2, 4]), (TET, [0, 1, 2, 3])],
                     r"cell 1 \(tetrahedron\) is degenerate"),
    }


@pytest.mark.parametrize("name", bad_meshes())
def test_bad_cells_are_named(tmp_path, name, capsys):
    pts, cells, msg = bad_meshes()[name]
    path = write_vtu(tmp_path / f"{name}.vtu", np.asarray(pts, float) + [0, 0, 0.01], cells)
    f = load_field(path, resample=(3, 3, 3))  # opening reads the XML: cells checked when read
    with pytest.raises(MeshError, match=rf"{name}\.vtu: {msg}"):
        _ = f.vector
    assert main(["info", str(path), "--resample", "3,3,3"]) == 0
    assert "cells are split and checked" in capsys.readouterr().out
    assert main(["info", str(path), "--resample", "3,3,3", "--stats"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{name}.vtu: cell" in err and "Traceback" not in err


def test_a_flat_mesh_is_named_when_opened(tmp_path):
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.7, 0.6, 0]], float)  # (no lattice)
    path = write_vtu(tmp_path / "flat.vtu", pts, [(TET, [0, 1, 2, 3])])
    with pytest.raises(ReaderError, match=r"flat\.vtu: every point lies at z = 0: the mesh has "
                                          "no volume"):
        load_field(path)


def test_no_vector_data_is_named(tmp_path):
    pts, cells = block((1, 1, 1))
    path = write_vtu(tmp_path / "n.vtu", pts + 0.1 * pts ** 2, cells,
                     point_data={"T": linear_t(pts)}, cell_data={"p": [1.0]})
    with pytest.raises(ReaderError, match=r"n\.vtu: no point data array 'U'; point data arrays:"
                                          r" T; cell data: p"):
        load_field(path)
    with pytest.raises(ReaderError, match=r"n\.vtu: resample 'spacing:-1': spacing:DX needs"):
        load_field(path, resample="spacing:-1")


# -- the command line ----------------------------------------------------------------------------
def test_resample_command_writes_the_field_once(tmp_path, capsys):
    pts, cells = block((3, 3, 3), hole=((1, 1, 1), (2, 2, 2)), kinds="poly")
    path = write_vtu(tmp_path / "m.vtu", pts, cells)
    out = tmp_path / "m.h5"
    assert main(["resample", str(path), "-o", str(out), "--resample", "13,13,13"]) == 0
    said = capsys.readouterr().out
    assert "13 x 13 x 13 grid" in said and "of 2197 nodes lie in no cell" in said
    f = load_field(out)
    g = load_field(path, resample=(13, 13, 13))
    np.testing.assert_array_equal(f.vector, g.vector)
    assert np.isnan(f.vector).any() and f.notes[0] == g.notes[0]
    assert not list(tmp_path.glob(".*tmp*"))  # written atomically: no temporary left
    assert main(["info", str(path), "--resample", "spacing:0.5"]) == 0
    assert "shape (7, 7, 7)" in capsys.readouterr().out
    assert main(["info", str(path), "--resample", "3,3"]) == 2
    assert "expected NX,NY,NZ" in capsys.readouterr().err


def test_a_scene_resamples_its_mesh_as_its_field_says(tmp_path):
    from flowkit.scene import load_scene, make_plan
    from flowkit.scene.model import SceneError

    pts, cells = block((2, 2, 2), kinds="poly")
    write_vtu(tmp_path / "m.vtu", pts, cells)
    text = ('version = 1\n[field]\nfile = "m.vtu"\nresample = "{}"\n[seeds]\n'
            'spec = "line:0.5,0.5,0.5:1.5,0.5,0.5:3"\n[styles.a]\n[[styles.a.bands]]\nwidth = 2\n')
    (tmp_path / "s.toml").write_text(text.format("5,6,7"))
    scene = load_scene(tmp_path / "s.toml")
    snap = make_plan(scene).snapshots[0]
    f = snap.load(scene.field.vector, **scene.field.load_options)
    assert f.grid.shape == (5, 6, 7) and not check_linear(f).any()
    (tmp_path / "s.toml").write_text(text.format("5,6"))
    with pytest.raises(SceneError, match=r"resample.*NX,NY,NZ"):
        load_scene(tmp_path / "s.toml")


def test_a_changed_vtm_piece_misses_the_scene_cache(tmp_path):
    """The .vtm only names its pieces: the lines depend on the internal .vtu's bytes."""
    from flowkit.scene import LinesCache, load_scene, make_plan

    pts, cells = block((2, 2, 2), kinds="poly")
    write_vtm(tmp_path, pts, cells)
    (tmp_path / "s.toml").write_text(
        'version = 1\n[field]\nfile = "case_5.vtm"\nresample = "5,5,5"\n[seeds]\n'
        'spec = "line:0.5,0.5,0.5:1.5,0.5,0.5:3"\n[styles.a]\n[[styles.a.bands]]\nwidth = 2\n')
    plan = make_plan(load_scene(tmp_path / "s.toml"))

    def key():
        cache = LinesCache(tmp_path / "cache")  # (a new one: no digest remembered)
        return cache.key(cache.inputs(plan, plan.snapshots[0]))

    before = key()
    vtm = (tmp_path / "case_5.vtm").read_bytes()
    write_vtm(tmp_path, pts, cells, point_data={"U": 2 * linear_u(pts), "T": linear_t(pts)})
    assert (tmp_path / "case_5.vtm").read_bytes() == vtm and key() != before


def test_cell_data_wherever_resample_is_taken(tmp_path, capsys):
    """--data cell on trace and sample (as on info and resample), data = "cell" in a scene:
    point data U is 5 along x, cell data 1 and 2 in the two cells."""
    from flowkit.io.lines_h5 import read_lines
    from flowkit.scene import load_scene, make_plan
    from flowkit.scene.model import SceneError

    pts, cells = block((2, 1, 1))
    path = write_vtu(tmp_path / "c.vtu", pts + [0, 0.1, 0], cells,
                     point_data={"U": np.tile([5.0, 0, 0], (len(pts), 1))},
                     cell_data={"U": [[1.0, 0, 0], [2.0, 0, 0]]})
    out = tmp_path / "l.h5"
    seed = ["--seeds", "line:0.2,0.5,0.5:0.2,0.6,0.5:2", "--max-length", "1.5", "--quiet",
            "--attributes", "speed", "--resample", "9,3,3"]
    assert main(["trace", str(path), "-o", str(out), *seed]) == 0
    assert np.allclose(read_lines(out).point_data["speed"], 5.0)
    assert main(["trace", str(path), "-o", str(out), *seed, "--data", "cell"]) == 0
    speed = read_lines(out).point_data["speed"]
    assert speed.min() == 1.0 and speed.max() <= 2.0
    out2 = tmp_path / "s.h5"
    assert main(["sample", str(out), str(path), "--attributes", "speed", "-o", str(out2),
                 "--rename", "speed=cell_speed", "--data", "cell", "--resample", "9,3,3"]) == 0
    # (at the float32 vertices the file holds: to their rounding)
    np.testing.assert_allclose(read_lines(out2).point_data["cell_speed"], speed, rtol=1e-6)
    capsys.readouterr()
    text = ('version = 1\n[field]\nfile = "c.vtu"\nresample = "9,3,3"\ndata = "{}"\n'
            '[seeds]\nspec = "line:0.5,0.5,0.5:1.5,0.5,0.5:3"\n[styles.a]\n'
            '[[styles.a.bands]]\nwidth = 2\n')
    (tmp_path / "s.toml").write_text(text.format("cell"))
    scene = load_scene(tmp_path / "s.toml")
    f = make_plan(scene).snapshots[0].load(scene.field.vector, **scene.field.load_options)
    assert set(np.unique(f.vector[..., 0])) == {1.0, 2.0}
    (tmp_path / "s.toml").write_text(text.format("cells"))
    with pytest.raises(SceneError, match=r"data.*\"point\" or \"cell\""):
        load_scene(tmp_path / "s.toml")


def test_a_scene_on_workers_resamples_as_its_field_says(tmp_path, monkeypatch):
    """Snapshots traced on Dask workers are loaded with the scene's resample and data."""
    import flowkit.distributed as dist
    from flowkit.scene import run_scene

    pts, cells = block((2, 2, 2), kinds="poly")
    for i in range(2):
        write_vtu(tmp_path / f"m_{i}.vtu", pts, cells)
    (tmp_path / "m.series").write_text(json.dumps({"file-series-version": "1.0", "files": [
        {"name": f"m_{i}.vtu", "time": float(i)} for i in range(2)]}))
    (tmp_path / "s.toml").write_text(
        'version = 1\n[field]\nseries = "m.series"\nresample = "5,6,7"\ndata = "point"\n'
        '[seeds]\nspec = "line:0.5,0.5,0.5:1.5,0.5,0.5:3"\n[styles.a]\n[[styles.a.bands]]\n'
        'width = 2\n')
    seen = {}

    def fake(*a, **kw):
        seen.update(kw)
        raise RuntimeError("stop here")

    monkeypatch.setattr(dist, "trace_distributed", fake)
    with pytest.raises(RuntimeError, match="stop here"):
        run_scene(tmp_path / "s.toml", workers=2, use_cache=False, report=lambda *a: None)
    assert seen["load"] == {"resample": "5,6,7", "data": "point"}
