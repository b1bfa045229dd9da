"""The PyVista bridge: grids in, lines out and back, and PyVista's own streamlines read as
Lines, so that a user can compare the two."""

import numpy as np
import pytest

from flowkit import Lines, datasets, trace
from flowkit.fields import from_pyvista
from flowkit.fields.analytic import ABCFlow
from flowkit.integrate import seeds

pv = pytest.importorskip("pyvista")


def _image(field):
    """The field as a pyvista.ImageData, point data in VTK's x-fastest order."""
    g = field.grid
    img = pv.ImageData(dimensions=g.shape, spacing=g.spacing, origin=g.origin)
    img.point_data["U"] = field.vector.transpose(2, 1, 0, 3).reshape(-1, 3)
    img.point_data["T"] = field.scalars["T"].transpose(2, 1, 0).reshape(-1)
    img.set_active_vectors("U")
    return img


def test_an_image_traces_the_lines_of_the_field_it_holds():
    room = datasets.hotroom()
    f = from_pyvista(_image(room))
    np.testing.assert_array_equal(f.vector, room.vector)
    np.testing.assert_array_equal(f.scalars["T"], room.scalars["T"])
    s = seeds.line((1, 1, 1), (9, 4, 9), 12)
    assert trace(f, s, max_length=5.0).equals(trace(room, s, max_length=5.0))


def test_a_rectilinear_grid_and_the_errors():
    x, y, z = np.array([0, 1, 3.0]), np.array([0, 2.0]), np.array([0, 1, 2, 4.0])
    r = pv.RectilinearGrid(x, y, z)
    u = np.random.default_rng(0).random((r.n_points, 3))
    r.point_data["vel"] = u
    f = from_pyvista(r)
    np.testing.assert_array_equal(f.grid.z, z)
    assert f.vector[2, 1, 3].tolist() == u[2 + 3 * (1 + 2 * 3)].tolist()  # x fastest in VTK
    with pytest.raises(TypeError, match="a pyvista.PolyData; flowkit reads ImageData and "
                                        "RectilinearGrid"):
        from_pyvista(pv.Sphere())
    img = pv.ImageData(dimensions=(3, 3, 3))
    img.cell_data["U"] = np.ones((img.n_cells, 3))
    with pytest.raises(ValueError, match="cell_data_to_point_data"):
        from_pyvista(img)


def test_lines_round_trip_through_polydata():
    room = datasets.hotroom()
    lines = trace(room, seeds.line((1, 1, 1), (9, 4, 9), 12), max_length=5.0,
                  attributes=["speed", "velocity"])
    poly = lines.to_pyvista()
    assert poly.n_lines == len(lines) and poly.n_points == lines.n_points
    assert "speed" in poly.point_data and "reason" in poly.cell_data
    back = Lines.from_pyvista(poly)
    np.testing.assert_array_equal(back.points, lines.points)
    np.testing.assert_array_equal(back.offsets, lines.offsets)
    np.testing.assert_array_equal(back.point_data["velocity"], lines.point_data["velocity"])
    np.testing.assert_array_equal(back.line_data["reason"], lines.line_data["reason"])


def test_pyvistas_own_streamlines_read_as_lines():
    f = ABCFlow().to_field(16, bounds=[[0, 2 * np.pi]] * 3)
    img = pv.ImageData(dimensions=f.grid.shape, spacing=f.grid.spacing, origin=f.grid.origin)
    img.point_data["U"] = f.vector.transpose(2, 1, 0, 3).reshape(-1, 3)
    img.set_active_vectors("U")
    src = pv.PolyData(np.array([[1.0, 2.0, 3.0], [4.0, 1.0, 0.5]]))
    out = img.streamlines_from_source(src, vectors="U", max_length=3.0,
                                      integration_direction="forward")
    theirs = Lines.from_pyvista(out)
    assert len(theirs) == 2 and "IntegrationTime" in theirs.point_data
    ours = trace(from_pyvista(img), src.points, max_length=3.0)
    # the same flow from the same seeds: the first vertices agree, both start at the seed
    np.testing.assert_allclose(theirs.points[theirs.offsets[:-1]], ours.points[ours.offsets[:-1]],
                               atol=1e-6)
