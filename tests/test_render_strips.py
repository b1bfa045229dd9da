"""The two strip stages: view-oriented strips built in the vertex shader (vertex pulling, the
default) or in a lines_adjacency geometry shader.  Both share every line of style code, so they
must draw the same picture; each stage's generated source holds only its own strip code."""

from __future__ import annotations

import numpy as np
import pytest
from render_scenes import helices, style

from flowkit.cli import main
from flowkit.io.lines_h5 import write_lines
from flowkit.lines import Lines
from flowkit.render import Band, Camera, ColorMap, LineRenderer, LineStyle, Style, WidthMap
from flowkit.render.shader_build import build_sources, shader_flags
from flowkit.render.style import Pattern, Shape, Transfer, TransferRange

GREY = (0.8, 0.8, 0.8, 1.0)
SIZE = (320, 240)
CAM = Camera(azimuth=30, elevation=20)

STYLES = {
    "halo": style(Band((0, 0, 0, 1), 1.5), Band((1, 1, 1, 1), 1.0, depth_offset=0.05),
                  background=GREY),
    "cmap_width": style(Band(ColorMap("viridis", "speed", (0.0, 1.0)),
                             WidthMap("speed", (0.0, 1.0), 0.5, 4.0)), background=GREY),
    "arrow": style(Band((0.9, 0.9, 0.9, 1), 3.0, shape=Shape("arrow", "arc", 0.1)),
                   Band(ColorMap("plasma", "speed", (0.0, 1.0)), 1.0, depth_offset=0.05),
                   background=GREY),
    "transfer": Style(
        styles={"focus": LineStyle((
                    Band(ColorMap("viridis", "speed", (0.0, 1.0)), 2.0,
                         pattern=Pattern((0, 0, 0, 1), "arc", 0.05, 0.5, 1.0, 0.6)),
                    Band((1, 1, 1, 1), 1.0, depth_offset=0.05))),
                "context": LineStyle((Band((0.4, 0.4, 0.4, 1), 1.0,
                                           shape=Shape("dash", "arc", 0.03)),))},
        transfer=Transfer("speed", (TransferRange((0.5, np.inf), "focus"),
                                    TransferRange((-np.inf, 0.5), "context")), 0.05),
        background=GREY),
}


def _render(lines, st, strips, **kw):
    with LineRenderer(lines, strips=strips, **kw) as r:
        img = r.render(st, SIZE, CAM)
        return img, r.n_drawn


@pytest.mark.parametrize("tolerance", [None, 0.0])
@pytest.mark.parametrize("name", list(STYLES))
def test_geometry_and_vertex_strips_draw_the_same_picture(name, tolerance):
    lines = helices(8, 200)
    st = STYLES[name]
    vert, n_v = _render(lines, st, "vertex", tolerance=tolerance)
    geom, n_g = _render(lines, st, "geometry", tolerance=tolerance)
    assert n_v == n_g  # the same points drawn (same level of detail)
    drawn = np.any(vert[..., :3] != 204, axis=2)
    assert drawn.mean() > 0.05  # a real picture, not two empty ones
    d = np.abs(vert.astype(int) - geom.astype(int)).max(axis=2)
    # tolerance: 99.5% of all pixels within 2/255, and at most 0.5% of the drawn pixels (edge
    # pixels where float rounding differs between the stages) further apart
    assert np.mean(d <= 2) > 0.995
    assert np.sum(d > 2) <= 0.005 * drawn.sum(), f"{np.sum(d > 2)} pixels differ"


def test_geometry_strips_keep_joins_continuous_at_a_sharp_corner():
    # a 90-degree corner with two points per leg: the mitred joins leave no gap and no spike
    pts = np.array([[-1, 0, 0], [0, 0, 0], [0, 0, 1]], float)
    lines = Lines(pts, [0, 3])
    st = style(Band((0, 0, 0, 1), 4.0), background=(1, 1, 1, 1), antialias="none")
    cam = Camera(azimuth=-90, elevation=0, projection="orthographic")
    with LineRenderer(lines, strips="geometry") as g, LineRenderer(lines) as v:
        a, b = g.render(st, (200, 200), cam), v.render(st, (200, 200), cam)
    assert np.any(a[..., 0] == 0)
    assert np.array_equal(a, b)


def test_each_stage_source_holds_only_its_own_strip_code():
    st = STYLES["transfer"]
    vsrc = build_sources(shader_flags(st, True, "vertex"))
    gsrc = build_sources(shader_flags(st, True, "geometry"))
    assert set(vsrc) == {"vertex_shader", "fragment_shader"}
    assert set(gsrc) == {"vertex_shader", "geometry_shader", "fragment_shader"}
    strip_code = ("strip_offset", "strip_vertex", "safe_dir", "u_half", "u_pad", "g_b")
    # vertex stage: the strip in the vertex shader, nothing of the geometry path
    for word in strip_code + ("gl_VertexID", "a_prev", "a_next"):
        assert word in vsrc["vertex_shader"], word
    for word in ("lines_adjacency", "EmitVertex", "vs_view", "vs_valid", "vs_attr"):
        assert word not in "".join(vsrc.values()), word
    # geometry stage: the vertex shader only fetches points; the strip is in the geometry shader
    for word in strip_code + ("gl_VertexID", "a_prev", "a_next"):
        assert word not in gsrc["vertex_shader"], word
    for word in strip_code + ("lines_adjacency", "EmitVertex", "vs_valid"):
        assert word in gsrc["geometry_shader"], word
    assert "gl_VertexID" not in gsrc["geometry_shader"]
    # the strip code appears once, and the style code is the same text for both stages
    assert sum(s.count("vec4 strip_offset(") for s in gsrc.values()) == 1
    assert vsrc["fragment_shader"] == gsrc["fragment_shader"]


def test_geometry_program_is_compiled_with_a_geometry_shader():
    st = STYLES["halo"]
    with LineRenderer(helices(2, 20), strips="geometry") as r, r.ctx:
        flags, prog = r.prepare(st)
        assert flags.strip_stage == "geometry"
        assert prog.geometry_vertices == 4  # max_vertices of the lines_adjacency shader
    with LineRenderer(helices(2, 20)) as r, r.ctx:
        assert r.prepare(st)[0].strip_stage == "vertex"
        assert r.prepare(st)[1].geometry_vertices == 0


def test_unknown_strip_stage_is_refused():
    with pytest.raises(ValueError, match="strips = 'tessellation'"):
        LineRenderer(helices(1, 10), strips="tessellation")
    with pytest.raises(ValueError, match="vertex, geometry"):
        shader_flags(STYLES["halo"], True, "fragment")


def test_cli_strips_option(tmp_path, capsys):
    from PIL import Image

    lines = helices(4, 80)
    h5 = tmp_path / "lines.h5"
    write_lines(lines, h5)
    sfile = tmp_path / "s.toml"
    sfile.write_text('version = 1\nbackground = "#ffffff"\n[[bands]]\ncolor = "#000000"\n'
                     'width = 1.5\n[[bands]]\ncolor = "#ff0000"\nwidth = 1\ndepth_offset = 0.05\n')
    imgs = {}
    for st in ("vertex", "geometry"):
        out = tmp_path / f"{st}.png"
        assert main(["render", str(h5), "--style", str(sfile), "-o", str(out), "--size",
                     "160x120", "--strips", st]) == 0
        imgs[st] = np.asarray(Image.open(out)).astype(int)
    assert np.any(imgs["geometry"][..., 1] < 100)
    assert np.mean(np.abs(imgs["vertex"] - imgs["geometry"]).max(axis=2) <= 2) > 0.995
    with pytest.raises(SystemExit) as e:  # argparse's choices
        main(["render", str(h5), "--style", str(sfile), "-o", str(tmp_path / "x.png"),
              "--strips", "mesh"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "--strips" in err and "'mesh'" in err
