"""Attributes added to lines already traced (flowkit.sample, flowkit sample): the values a
trace computes, bit for bit, from this or another snapshot or grid, NaN outside it and counted."""

import numpy as np
import pytest

import flowkit
from flowkit import Field, datasets, read_lines, sample, trace, write_lines
from flowkit.cli import main
from flowkit.integrate import seeds
from flowkit.integrate.sample import nan_counts

NAMES = ["speed", "velocity", "T", "vorticity", "vorticity_magnitude"]


@pytest.fixture(scope="module")
def room():
    return datasets.hotroom()


@pytest.fixture(scope="module")
def bare(room):
    return trace(room, seeds.line((1, 1, 1), (9, 4, 9), 20), max_length=8.0, direction="both")


def test_sampled_attributes_equal_the_traced_ones_bit_for_bit(room, bare):
    traced = trace(room, seeds.line((1, 1, 1), (9, 4, 9), 20), max_length=8.0,
                   direction="both", attributes=NAMES)
    np.testing.assert_array_equal(traced.points, bare.points)
    got = sample(bare, room, NAMES)
    for n in NAMES:
        np.testing.assert_array_equal(got.point_data[n], traced.point_data[n], err_msg=n)
    assert got.units["speed"] == "m/s" and got.units["T"] == "K"
    assert nan_counts(got) == dict.fromkeys(NAMES, 0)
    assert got.points is bare.points and not bare.point_data  # shared, the input untouched


def test_another_snapshot_under_another_name(room, bare):
    early = datasets.hotroom(snapshot=0)
    got = sample(sample(bare, room, ["T"]), early, ["T"], rename={"T": "T_400s"})
    expect, _ = early.sample_scalar("T", bare.points)
    np.testing.assert_array_equal(got.point_data["T_400s"], expect)
    assert not np.array_equal(got.point_data["T_400s"], got.point_data["T"])
    assert set(nan_counts(got)) == {"T", "T_400s"}


def test_vertices_outside_another_grid_get_nan_and_are_counted(room, bare):
    g = room.grid
    half = flowkit.Grid.from_axes(g.x[: g.x.size // 2], g.y, g.z)
    small = Field(half, room.vector[: g.x.size // 2], {"T": room.scalars["T"][: g.x.size // 2]})
    got = sample(bare, small, ["T", "speed"])
    out = bare.points[:, 0] > half.x[-1]
    assert out.any() and (~out).any()
    assert np.isnan(got.point_data["T"][out]).all() and np.isfinite(got.point_data["T"][~out]).all()
    assert nan_counts(got) == {"T": int(out.sum()), "speed": int(out.sum())}


def test_what_cannot_be_sampled_is_refused_with_the_reason(room, bare):
    with pytest.raises(ValueError, match="cannot sample 'time' onto lines: integration time"):
        sample(bare, room, ["time"])
    with pytest.raises(ValueError, match="arc length accumulates along the trace"):
        sample(bare, room, "arc_length")
    with pytest.raises(ValueError, match=r"'distance_to_seed': these lines do not carry their "
                                         r"seeds \(line data 'seed'\); pass the points"):
        sample(bare, room, ["distance_to_seed"])
    with pytest.raises(KeyError, match="unknown attribute 'rho'"):
        sample(bare, room, ["rho"])
    with pytest.raises(ValueError, match="rename names p, which are not sampled"):
        sample(bare, room, ["T"], rename={"p": "q"})


def test_distance_to_seed_from_the_seeds_the_lines_were_traced_from(room, bare):
    pts = seeds.line((1, 1, 1), (9, 4, 9), 20)
    traced = trace(room, pts, max_length=8.0, direction="both", attributes=["distance_to_seed"])
    got = sample(bare, room, ["distance_to_seed"], seeds=pts)
    np.testing.assert_array_equal(got.point_data["distance_to_seed"],
                                  traced.point_data["distance_to_seed"])
    with pytest.raises(ValueError, match="seed_id runs to 19, but seeds= has 5 points"):
        sample(bare, room, ["distance_to_seed"], seeds=pts[:5])
    with pytest.raises(ValueError, match=r"the \(n, 3\) points the lines were traced from"):
        sample(bare, room, ["distance_to_seed"], seeds=pts[:, :2])
    with pytest.raises(ValueError, match="seeds are for 'distance_to_seed'"):
        sample(bare, room, ["T"], seeds=pts)


def test_cli_writes_the_lines_with_the_new_attributes(room, bare, tmp_path, capsys):
    write_lines(bare, tmp_path / "l.h5", position_dtype="float64")
    out = tmp_path / "more.h5"
    rc = main(["sample", str(tmp_path / "l.h5"), str(datasets.hotroom_path()), "--attributes",
               "T,speed", "--time", "400", "--rename", "T=T_400s", "-o", str(out)])
    text = capsys.readouterr().out
    assert rc == 0 and "T_400s" in text and "speed" in text
    back = read_lines(out)
    assert back.points.dtype == np.float64 and back.units["T_400s"] == "K"
    early = datasets.hotroom(snapshot=0)
    np.testing.assert_array_equal(back.point_data["T_400s"],
                                  early.sample_scalar("T", bare.points)[0])
    rc = main(["sample", str(tmp_path / "l.h5"), str(datasets.hotroom_path()), "--attributes",
               "time", "-o", str(tmp_path / "x.h5")])
    err = capsys.readouterr().err
    assert rc == 2 and "cannot sample 'time'" in err and not (tmp_path / "x.h5").exists()
