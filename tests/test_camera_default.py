"""The default camera finds the view on any domain, and one precedence decides the camera:
command line over scene over style over the automatic view."""

from __future__ import annotations

import math

import numpy as np
import pytest
from render_scenes import style

from flowkit.cli import main
from flowkit.lines import Lines
from flowkit.render import Band, Camera, render_lines
from flowkit.render.style import style_from_dict
from flowkit.scene import make_plan
from flowkit.scene.model import scene_from_dict

WHITE = (1, 1, 1, 1)
SIZE = (320, 180)


def box_lines(extent) -> Lines:
    """The 12 edges of a box from the origin to ``extent``, as lines."""
    e = np.asarray(extent, float)
    corners = np.array(np.meshgrid(*[[0, 1]] * 3, indexing="ij")).reshape(3, -1).T * e
    parts = []
    t = np.linspace(0, 1, 16)[:, None]
    for i in range(8):
        for j in range(i + 1, 8):
            if np.sum(corners[i] != corners[j]) == 1:
                parts.append(Lines(corners[i] + t * (corners[j] - corners[i]), [0, 16]))
    return Lines.concatenate(parts)


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
@pytest.mark.parametrize("extent", [(1, 1, 1), (1, 10, 1), (1, 30, 7), (10, 1, 1)])
def test_default_view_lays_the_longest_axis_along_the_image_and_fills_it(extent, projection):
    lines = box_lines(extent)
    cam = Camera(projection=projection)
    s = cam.setup(lines.bounds(), *SIZE)
    longest = np.eye(3)[int(np.argmax(extent))]
    on_image = np.array([s.view[0, :3] @ longest, s.view[1, :3] @ longest])
    angle = math.degrees(math.atan2(min(abs(on_image)), max(abs(on_image))))
    assert angle <= 10, f"{extent}: longest axis {angle:.1f} degrees off the image's axes"
    img = render_lines(lines, style(Band((0, 0, 0, 1), 1.0), background=WHITE,
                                    antialias="none"), SIZE, cam)
    drawn = np.any(img[:, :, :3] < 128, axis=2)
    rows, cols = np.flatnonzero(drawn.any(axis=1)), np.flatnonzero(drawn.any(axis=0))
    along = 0 if abs(on_image[0]) >= abs(on_image[1]) else 1
    span = ((cols[-1] - cols[0] + 1) / SIZE[0], (rows[-1] - rows[0] + 1) / SIZE[1])[along]
    if extent != (1, 1, 1):  # a cube's faces all fit the height first
        assert along == 0, f"{extent}: the longest axis is not along the image's width"
        assert span >= 0.7, f"{extent}: the domain fills {span:.0%} of the image along it"
    else:
        assert max((cols[-1] - cols[0] + 1) / SIZE[0], (rows[-1] - rows[0] + 1) / SIZE[1]) >= 0.7


def test_default_view_looks_along_the_thinnest_axis_and_keeps_z_up_on_a_cube():
    b = np.array([[0, 0.076], [0, 2.18], [0, 0.52]])  # a tall, thin cavity
    wide, tall = Camera().resolve(b, 1600, 900), Camera().resolve(b, 600, 900)
    assert wide.view[1] == "x" and wide.up == (0.0, 0.0, 1.0)  # y along the width
    assert tall.view[1] == "x" and tall.up == (0.0, 1.0, 0.0)  # y along the height
    cube = np.array([[0, 1], [0, 1], [0, 1]])
    assert Camera().resolve(cube, 800, 600).up == (0.0, 0.0, 1.0)
    # a cube: look along the axis the lines travel least along (flow in the x-z plane)
    assert Camera().resolve(cube, 800, 600, travel=(5.0, 0.1, 3.0)).view[1] == "y"
    assert Camera().resolve(cube, 800, 600, travel=(5.0, 3.0, 0.1)).view[1] == "z"
    assert Camera(azimuth=10).resolve(b, 800, 600) == Camera(azimuth=10)  # given: kept


def test_a_direction_given_replaces_the_whole_direction_below_it():
    styled = style_from_dict({"version": 1, "bands": [{"width": 1}],
                              "camera": {"view": "+x", "up": [0, 1, 0]}}).camera
    assert styled.over(azimuth=30.0).view is None  # an angle clears the style's view
    assert styled.over(azimuth=30.0).direction(np.array([0, 1.0, 0])) == pytest.approx(
        Camera(azimuth=30.0, up=(0, 1, 0)).direction(np.array([0, 1.0, 0])))
    angled = Camera(azimuth=30.0, elevation=10.0)
    assert angled.over(view="-z") == Camera(view="-z")  # a view clears the angles
    assert styled.over(zoom=2.0).view == "+x"  # other keys leave the direction


def test_scene_camera_over_style_camera_over_default(tmp_path):
    doc = {"version": 1, "field": {"dataset": "hotroom"}, "seeds": {"spec": "points:1,1,1"},
           "styles": {"s": {"bands": [{"width": 1}], "camera": {"view": "+x", "zoom": 2.0}}},
           "views": {"a": {"camera": {"azimuth": 20}}, "b": {}}}
    sc = scene_from_dict(doc, tmp_path / "scene.toml")
    assert sc.views["a"].camera.view is None and sc.views["a"].camera.azimuth == 20
    assert sc.views["a"].camera.zoom == 2.0  # keys the scene does not give: the style's
    assert sc.views["b"].camera.view == "+x"
    plain = scene_from_dict({**doc, "styles": {"s": {"bands": [{"width": 1}]}}},
                            tmp_path / "scene.toml")
    assert plain.views["b"].camera.automatic
    text = make_plan(sc).explain()  # the camera as the scene over the style makes it
    assert "view 'a': style 's', 1600x900, camera azimuth 20 elevation 25, perspective" in text
    assert "view 'b': style 's', 1600x900, camera view +x, perspective" in text
    text = make_plan(plain).explain()  # the room is 10 x 5 x 10 m, y up: seen from above
    assert ("camera automatic view (view +y up 0,0,1 on the field's bounds; chosen on the "
            "lines' bounds when drawn)") in text


def test_render_command_line_over_style_and_view_minus_x_parses(tmp_path, capsys):
    from flowkit.io.lines_h5 import write_lines

    path = write_lines(box_lines((1, 4, 2)), tmp_path / "box.h5")
    st = tmp_path / "s.toml"
    st.write_text('version = 1\nbackground = "#ffffff"\n[camera]\nview = "+z"\n'
                  '[[bands]]\ncolor = "#000000"\nwidth = 1\n')
    out = tmp_path / "a.png"
    assert main(["render", str(path), "--style", str(st), "-o", str(out), "--size", "160x90",
                 "--view", "-x"]) == 0
    assert "view -x" in capsys.readouterr().out
    assert main(["render", str(path), "--style", str(st), "-o", str(out), "--size", "160x90",
                 "--azimuth", "30"]) == 0
    assert "azimuth 30" in capsys.readouterr().out
    assert main(["render", str(path), "--style", str(st), "-o", str(out), "--size", "160x90"]) == 0
    assert "view +z" in capsys.readouterr().out
    st.write_text('version = 1\n[[bands]]\ncolor = "#000000"\nwidth = 1\n')
    assert main(["render", str(path), "--style", str(st), "-o", str(out), "--size", "160x90"]) == 0
    assert "view -x up 0,0,1 (automatic)" in capsys.readouterr().out


def test_default_view_with_a_given_up_looks_across_it():
    room = np.array([[0, 10], [0, 5], [0, 10]])  # y up, as the heated room
    cam = Camera(up=(0, 1, 0)).resolve(room, 1600, 900)
    assert cam.view in ("+x", "-x", "+z", "-z") and cam.up == (0, 1, 0)
    s = cam.setup(room, 1600, 900)
    assert s.view[1, :3] @ np.array([0, 1.0, 0]) == pytest.approx(1.0)  # y points up
