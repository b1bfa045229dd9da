"""Lines as a pipeline user reaches them: a summary for print, lines by reason, arc lengths,
errors that say what was expected, and the bridges to pandas and xarray."""

import numpy as np
import pytest

from flowkit import Lines, datasets, read_lines, trace, write_lines
from flowkit.integrate import seeds
from flowkit.integrate.reasons import Reason


@pytest.fixture(scope="module")
def lines():
    room = datasets.hotroom()
    return trace(room, seeds.line((1, 1, 1), (9, 4, 9), 24), max_length=6.0, direction="both",
                 attributes=["speed", "T", "velocity"])


def _toy():
    pts = np.array([[0, 0, 0], [3, 4, 0], [3, 4, 12], [1, 1, 1], [5, 5, 5.0]])
    return Lines(pts, [0, 3, 4, 5], {"s": np.arange(5.0), "v": np.ones((5, 3))},
                 {"reason": np.array([1, 0, 7], np.int8)})


def test_print_is_a_short_summary(lines, tmp_path):
    text = repr(lines)
    assert len(text.splitlines()) < 20 and len(text) < 1000
    assert f"{len(lines)} lines, {lines.n_points} vertices" in text
    assert "speed float64 [m/s]" in text and "velocity float64 x3" in text
    assert "reasons:" in text and "reasons backward:" in text
    write_lines(lines, tmp_path / "x.h5")
    back = repr(read_lines(tmp_path / "x.h5"))
    assert len(back.splitlines()) < 20 and f"{len(lines)} lines" in back
    assert lines._repr_html_().startswith("<pre>")


def test_field_prints_its_summary_without_reading_data():
    from flowkit.fields import load_field

    f = load_field(datasets.hotroom_path())
    text = repr(f)
    assert "U [m/s]: vector (3), float32" in text and not f.vector_in_memory()
    assert len(text.splitlines()) < 20


def test_vertex_counts_arc_lengths_and_reasons():
    toy = _toy()
    np.testing.assert_array_equal(toy.n_vertices, [3, 1, 1])
    np.testing.assert_allclose(toy.arc_length(), [5.0 + 12.0, 0.0, 0.0])
    assert len(toy.where(reason="max_length")) == 1
    sel = toy.where(reason=["out_of_domain", Reason.SEED_OUTSIDE])
    np.testing.assert_array_equal(sel.line_data["reason"], [0, 7])
    both = toy.where(np.array([True, True, False]), reason="out_of_domain")
    assert len(both) == 1 and both.n_points == 1
    with pytest.raises(ValueError, match="unknown reason 'maxlength'; reasons: out_of_domain"):
        toy.where(reason="maxlength")
    with pytest.raises(ValueError, match="3 booleans"):
        toy.where([True])


def test_both_directions_match_either_end(lines):
    for r in ("max_length", "out_of_domain", "stagnation"):
        sel = lines.where(reason=r)
        code = Reason[r.upper()]
        assert np.all((sel.line_data["reason"] == code) | (sel.line_data["reason_backward"] == code))


def test_wrong_arguments_say_what_was_expected():
    toy = _toy()
    np.testing.assert_array_equal(toy.line_attribute("s", 0), [0, 1, 2])
    np.testing.assert_array_equal(toy.line_points(-1), [[5, 5, 5]])
    with pytest.raises(TypeError, match=r"line_attribute\(name, i\): name is an attribute's name"):
        toy.line_attribute(0, "s")
    with pytest.raises(KeyError, match="no per-vertex attribute 'T' \\(available: s, v\\)"):
        toy.line_attribute("T", 0)
    with pytest.raises(IndexError, match="line 3 out of range for 3 lines"):
        toy.line_points(3)


def test_one_line_holds_its_points_and_all_its_data(lines):
    i = 5
    one = lines[i]
    a, b = lines.offsets[i], lines.offsets[i + 1]
    np.testing.assert_array_equal(one.points, lines.points[a:b])
    assert set(one.point_data) == set(lines.point_data) == {"speed", "T", "velocity"}
    for k, v in lines.point_data.items():
        np.testing.assert_array_equal(one.point_data[k], v[a:b])
        np.testing.assert_array_equal(one.point_data[k], lines.line_attribute(k, i))
    assert set(one.line_data) == set(lines.line_data)
    for k, v in lines.line_data.items():
        np.testing.assert_array_equal(one.line_data[k], v[i:i + 1])
    assert repr(one).startswith("<Lines: 1 line, ")
    # iteration: every line once, in order
    assert [x.n_points for x in lines] == list(lines.n_vertices)
    assert lines[-1].equals(lines[len(lines) - 1])


def test_selections_take_what_they_say_or_refuse():
    toy = _toy()
    assert toy[[2, 0]].line_data["reason"].tolist() == [7, 1]  # in the order given
    assert toy[[-1]].equals(toy[2]) and toy[np.array([], int)].n_points == 0
    with pytest.raises(IndexError, match="line -4 out of range for 3 lines"):
        toy[[0, -4]]
    with pytest.raises(IndexError, match=r"one boolean per line \(3\), got shape \(2,\)"):
        toy[np.array([True, False])]
    with pytest.raises(TypeError, match=r"the per-vertex attribute is lines.point_data\['s'\]"):
        toy["s"]
    with pytest.raises(TypeError, match="takes a line number, a slice, a boolean per line or "
                                        "integer line numbers, got 1.5"):
        toy[1.5]
    with pytest.raises(TypeError, match=r"got \[0.0, 1.0\]"):
        toy[[0.0, 1.0]]
    with pytest.raises(ValueError, match=r"first part has \[s, v\] per vertex and \[reason\] "
                                         r"per line, another \[s\] and \[reason\]"):
        Lines.concatenate([toy, Lines(toy.points, toy.offsets, {"s": toy.point_data["s"]},
                                      toy.line_data)])


def test_to_pandas_is_one_row_per_vertex(lines):
    pytest.importorskip("pandas")
    df = lines.to_pandas()
    assert len(df) == lines.n_points
    i = 5
    rows = df[df.line == i]
    np.testing.assert_array_equal(rows[["x", "y", "z"]].to_numpy(), lines.line_points(i))
    np.testing.assert_array_equal(rows.vertex, np.arange(lines.n_vertices[i]))
    np.testing.assert_array_equal(rows.velocity_y, lines.line_attribute("velocity", i)[:, 1])
    assert set(rows.reason) == {Reason(lines.line_data["reason"][i]).label}


def test_to_xarray_is_the_ragged_layout_not_its_cross_product(lines):
    pytest.importorskip("xarray")
    ds = lines.to_xarray()
    assert ds.sizes == {"trajectory": len(lines), "obs": lines.n_points, "velocity_component": 3}
    assert int(ds.rowSize.sum()) == lines.n_points and ds.speed.attrs["units"] == "m/s"
    df = ds[["x", "y", "z", "speed"]].to_dataframe()
    assert len(df) == lines.n_points
    np.testing.assert_array_equal(df.speed.to_numpy(), lines.point_data["speed"])


def test_trace_takes_the_seed_specs_of_the_cli():
    room = datasets.hotroom()
    a = trace(room, "line:1,1,1:9,4,9:24", max_length=6.0)
    b = trace(room, seeds.line((1, 1, 1), (9, 4, 9), 24), max_length=6.0)
    assert a.equals(b)
    hot = trace(room, "where:T > 302:50", max_length=2.0)
    assert len(hot) == 50
    even = trace(room, "even:1/8d", max_length=6.0)
    assert len(even) > 3 and (even.line_data["reason"] == Reason.TOO_CLOSE).any()
    with pytest.raises(ValueError, match="not a seed file nor a known form"):
        trace(room, "nonsense:3")


def test_written_as_float64_lines_read_back_equal(lines, tmp_path):
    write_lines(lines, tmp_path / "d.h5", position_dtype="float64")
    assert read_lines(tmp_path / "d.h5").equals(lines)
    write_lines(lines, tmp_path / "f.h5")
    back = read_lines(tmp_path / "f.h5")
    assert back.points.dtype == np.float32 and not back.equals(lines)
    assert back.equals(lines, atol=1e-5)


def test_render_lines_without_a_style_uses_the_clis_default(lines):
    from flowkit.render import default_style, render_lines

    img = render_lines(lines, size=(160, 90))
    same = render_lines(lines, default_style(list(lines.point_data)),
                        size=(160, 90))
    np.testing.assert_array_equal(img, same)
    background = img[0, 0]
    assert (img != background).any(axis=-1).mean() > 0.01  # lines were drawn
