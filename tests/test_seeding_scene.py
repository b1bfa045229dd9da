"""Scenes accept every seed kind: evenly spaced lines (with pruning), density and where seeds,
checked when the scene loads as far as no field is needed."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from flowkit.integrate.reasons import Reason
from flowkit.io.lines_h5 import read_lines
from flowkit.scene import SceneError, load_scene, make_plan, run_scene


def write(tmp_path, seeds, style_attr=None, trace=""):
    color = (f'{{ cmap = "viridis", attribute = "{style_attr}", range = [0, 3] }}'
             if style_attr else '"#203060"')
    p = tmp_path / "scene.toml"
    p.write_text(textwrap.dedent(f"""\
        version = 1
        [field]
        dataset = "hotroom"
        snapshot = -1
        [seeds]
        {seeds}
        [trace]
        max_length = 4.0
        stagnation = 1e-4
        {trace}
        [styles.plain]
        [[styles.plain.bands]]
        color = {color}
        width = 2
        [views.v]
        size = [96, 64]
        [outputs]
        lines = "lines.h5"
        """))
    return p


def test_even_scene_with_pruning_and_a_later_attribute(tmp_path):
    path = write(tmp_path, 'spec = "even:1/8d:0.6"\nprune = "0.8:0.6"')
    scene = load_scene(path)
    assert scene.trace.direction == "both" and scene.prune == (0.8, 0.6)
    assert "pruned at distance 0.8 over 60% of a line" in make_plan(scene).explain()
    res = run_scene(path, report=None)
    lines = read_lines(tmp_path / "lines.h5")
    assert res.snapshots[0].n_lines == len(lines) > 5
    assert lines.attrs["seeding"] == "even" and lines.attrs["dtest"] == 0.6
    assert (lines.line_data["reason"] == Reason.TOO_CLOSE).any()
    assert "pruned_seed_id" in lines.attrs
    assert res.snapshots[0].images["v"].is_file()
    # distance_to_seed added later: computed on the cached vertices from each line's own seed
    write(tmp_path, 'spec = "even:1/8d:0.6"\nprune = "0.8:0.6"', style_attr="distance_to_seed")
    res = run_scene(path, report=None)
    assert res.snapshots[0].action == "extend"
    ext = read_lines(tmp_path / "lines.h5")
    seed_of = np.repeat(ext.line_data["seed"], ext.lengths, axis=0)
    np.testing.assert_allclose(ext.point_data["distance_to_seed"],
                               np.linalg.norm(ext.points - seed_of, axis=1), atol=1e-5)  # float32


def test_data_seeds_in_a_scene(tmp_path):
    path = write(tmp_path, 'spec = "where:T > 300.5:12:1"', trace='direction = "forward"')
    res = run_scene(path, report=None)
    assert res.snapshots[0].n_lines == 12
    path = write(tmp_path, 'spec = "density:10:speed"')
    assert run_scene(path, report=None).snapshots[0].n_lines == 10


@pytest.mark.parametrize("seeds, msg", [
    ('spec = "where:T + 1 > 3:10"', r"token '\+' at position 2 is not allowed"),
    ('spec = "even:0.5:0.7"', "DTEST 0.7 must be smaller than DSEP 0.5"),
    ('spec = "density:0:speed"', "must be n, an integer >= 1"),
    ('spec = "even:1/8d"\nprune = "x"', r"prune = 'x' is not allowed"),
])
def test_bad_seed_specs_are_refused_when_the_scene_loads(tmp_path, seeds, msg):
    with pytest.raises(SceneError, match=msg):
        load_scene(write(tmp_path, seeds))
