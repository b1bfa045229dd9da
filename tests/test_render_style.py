"""Style files: validation errors name the file, key, value and what is allowed; shader source
holds only what the style needs; parameter changes with the same flags do not recompile."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from render_scenes import FACE_ON, helices, straight, style

from flowkit.cli import main
from flowkit.io.lines_h5 import write_lines
from flowkit.render import (
    Band,
    ColorMap,
    LineRenderer,
    RenderContextError,
    StyleError,
    WidthMap,
    load_style,
)
from flowkit.render import context as render_context
from flowkit.render.shader_build import build_sources, program_cache, shader_flags

EXAMPLES = Path(__file__).resolve().parent.parent / "examples" / "styles"
OK_BAND = '[[bands]]\ncolor = "#000000"\nwidth = 2\n'

BAD = {
    "no_version": (OK_BAND, ["missing key 'version'"]),
    "version_2": ("version = 2\n" + OK_BAND, ["version = 2", "expected 1"]),
    "unknown_top": ("version = 1\ncolour = 'red'\n" + OK_BAND, ["unknown key 'colour'", "background"]),
    "unknown_band_key": ("version = 1\n[[bands]]\nwidht = 2\n", ["band 1", "unknown key 'widht'"]),
    "bad_cmap": (("version = 1\n[[bands]]\ncolor = { cmap = 'not_a_cmap_x', attribute = 'T', "
                  "range = [0, 1] }\n"), ["band 1", "color.cmap = 'not_a_cmap_x'", "cmap"]),
    "negative_width": ("version = 1\n[[bands]]\nwidth = -1\n", ["width = -1", ">= 0"]),
    "colour_component": ("version = 1\n[[bands]]\ncolor = [1.5, 0, 0]\n", ["color[0] = 1.5", "<= 1"]),
    "bad_hex": ("version = 1\n[[bands]]\ncolor = '#12345'\n", ["color = '#12345'", "#rrggbb"]),
    "width_map_missing": (("version = 1\n[[bands]]\nwidth = { attribute = 'speed', "
                           "range = [0, 1], min = 1 }\n"), ["band 1.width", "missing key 'max'"]),
    "empty_range": (("version = 1\n[[bands]]\ncolor = { cmap = 'viridis', attribute = 'T', "
                     "range = [2, 2] }\n"), ["color.range", "low != high"]),
    "units": ("version = 1\nunits = 'inches'\n" + OK_BAND, ["units = 'inches'", "'pixels' or 'world'"]),
    "projection": ("version = 1\n" + OK_BAND + "[camera]\nprojection = 'fisheye'\n",
                   ["[camera]", "projection = 'fisheye'", "'perspective' or 'orthographic'"]),
    "injection": (("version = 1\n[[bands]]\ncolor = { cmap = 'viridis', "
                   "attribute = 'T; discard', range = [0, 1] }\n"), ["color.attribute = 'T; discard'", "a name of letters"]),
    "negative_depth": ("version = 1\n[[bands]]\ndepth_offset = -0.1\n", ["depth_offset = -0.1"]),
    "no_bands": ("version = 1\nscale = 2\n", ["exactly one of [[bands]]"]),
    "too_many_bands": ("version = 1\n" + OK_BAND * 9, ["9 bands", "at most 8"]),
    "zero_scale": ("version = 1\nscale = 0\n" + OK_BAND, ["scale = 0", "> 0"]),
    "samples": ("version = 1\nsamples = 3\n" + OK_BAND, ["samples = 3", "1, 2, 4, 8 or 16"]),
    "not_toml": ("version = 1\n[[bands]\n", ["not valid TOML"]),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_style_file_gets_its_error(tmp_path, name):
    text, parts = BAD[name]
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    with pytest.raises(StyleError) as e:
        load_style(path)
    msg = str(e.value)
    assert str(path) in msg
    for p in parts:
        assert p in msg, f"{p!r} not in {msg!r}"


def test_example_styles_load():
    names = sorted(p.name for p in EXAMPLES.glob("*.toml"))
    assert "halo.toml" in names
    for p in EXAMPLES.glob("*.toml"):
        load_style(p)


def test_python_model_is_validated_like_files():
    with pytest.raises(StyleError, match="band 1: width = -2"):
        style(Band((0, 0, 0, 1), -2.0))
    with pytest.raises(StyleError, match="color.cmap = 'nope_cmap'"):
        style(Band(ColorMap("nope_cmap", "T", (0, 1)), 1.0))


def test_missing_or_vector_attribute_is_a_clear_error():
    lines = straight((-1, 0, 0), (1, 0, 0), T=1.0)
    lines.point_data["velocity"] = np.zeros((lines.n_points, 3))
    with LineRenderer(lines) as r:
        with pytest.raises(StyleError, match="'pressure'.*available: T, velocity"):
            r.render(style(Band(ColorMap("viridis", "pressure", (0, 1)), 1.0)), (32, 32), FACE_ON)
        with pytest.raises(StyleError, match="'velocity' has shape"):
            r.render(style(Band(ColorMap("viridis", "velocity", (0, 1)), 1.0)), (32, 32), FACE_ON)


# -- shader source ----------------------------------------------------------------------------
def sources(s, msaa=True) -> str:
    return "\n".join(build_sources(shader_flags(s, msaa)).values())


def test_plain_style_source_has_no_colormap_width_map_or_depth_code():
    src = build_sources(shader_flags(style(Band((0.1, 0.2, 0.3, 1.0), 2.0)), True))
    frag, vert = src["fragment_shader"], src["vertex_shader"]
    for word in ("sampler", "texture(", "u_cmap", "u_crange", "u_wmap", "g_attr", "gl_FragDepth",
                 "u_depth", "u_color1"):
        assert word not in frag, word
    assert "u_color0" in frag and "u_width0" in frag
    assert "u_attr" not in vert and "g_attr" not in vert  # no attribute fetched at all
    assert vert.count("sampler2D") == 1  # only the point positions


def test_colormap_and_width_map_styles_include_their_code_and_only_their_bands():
    s = style(Band(ColorMap("viridis", "secret_attr_name", (0, 1)), 2.0),
              Band((1, 1, 1, 1), WidthMap("other_attr", (0, 1), 1, 3), depth_offset=0.1),
              Band((0, 0, 0, 1), 1.0))
    src = sources(s)
    assert "uniform sampler2D u_cmap0;" in src and "texture(u_cmap0" in src
    assert "u_cmap1" not in src and "u_cmap2" not in src  # one sampler: one colormapped band
    assert "u_wmap1" in src and "u_wmap0" not in src and "u_wmap2" not in src
    assert "sampler2D u_attr0;" in src and "sampler2D u_attr1;" in src and "u_attr2" not in src
    assert "gl_FragDepth" in src and all(f"u_color{i}" in src for i in (1, 2))
    assert "u_color3" not in src and "u_width3" not in src
    # no style string reaches the source: attribute and colormap names are slots and textures
    for text in ("secret_attr_name", "other_attr", "viridis"):
        assert text not in src


def test_parameter_change_with_same_flags_updates_uniforms_only():
    lines = helices(3, 50)
    lines.point_data["T"] = np.linspace(0, 1, lines.n_points) ** 2  # curved, as speed: same flags
    base = style(Band(ColorMap("viridis", "speed", (0, 1)), 2.0), Band((0, 0, 0, 1), 1.0, 0.1))
    with LineRenderer(lines) as r:
        cache = program_cache(r.ctx)
        first = r.render(base, (64, 64))
        n = cache.compiles
        prog = r.prepare(base)[1]
        band0, band1 = base.line_style.bands
        changed = [
            dataclasses.replace(base, scale=1.5, background=(0, 0, 0, 1)),
            style(Band(ColorMap("magma", "T", (1, 0)), 3.0), Band((1, 0, 0, 1), 2.0, 0.3)),
            style(band0, dataclasses.replace(band1, color=(0.2, 0.9, 0.1, 1.0))),
        ]
        images = [r.render(s, (64, 64)) for s in changed]
        assert cache.compiles == n  # no new program
        assert all(r.prepare(s)[1] is prog for s in changed)
        assert all(not np.array_equal(first, im) for im in images)  # the uniforms did change
        r.render(style(band0, band1, Band((1, 1, 1, 1), 1.0)), (64, 64))  # one more band
        assert cache.compiles == n + 1


def test_no_gl_context_error_says_what_to_install(monkeypatch):
    def fail(*a, **k):
        raise Exception("libEGL.so.1: cannot open shared object file")  # noqa: TRY002 -- as glcontext does

    monkeypatch.setattr(render_context.moderngl, "create_standalone_context", fail)
    with pytest.raises(RenderContextError) as e:
        render_context.create_context("egl")
    assert "libegl1" in str(e.value) and "libgl1-mesa-dri" in str(e.value)
    assert "libEGL.so.1" in str(e.value)


# -- CLI --------------------------------------------------------------------------------------
def test_cli_renders_lines_file(tmp_path, capsys):
    lines = helices(4, 80)
    lines.point_data["T"] = np.linspace(295, 310, lines.n_points)
    h5 = tmp_path / "lines.h5"
    write_lines(lines, h5)
    out = tmp_path / "out.png"
    rc = main(["render", str(h5), "--style", str(EXAMPLES / "temperature_width.toml"), "-o",
               str(out), "--size", "96x64", "--azimuth", "30", "--projection", "orthographic"])
    assert rc == 0
    from PIL import Image

    img = np.asarray(Image.open(out))
    assert img.shape == (64, 96, 4)
    assert np.any(img[:, :, :3] < 100)  # lines were drawn on the white background
    assert not list(tmp_path.glob(".*tmp*"))  # atomic write left no temporary file
    assert main(["render", str(h5), "--style", str(EXAMPLES / "halo.toml"), "-o", str(out),
                 "--size", "96by64"]) == 2
    assert "--size '96by64'" in capsys.readouterr().err
    assert main(["render", str(h5), "--style", str(EXAMPLES / "halo.toml"), "-o", str(out),
                 "--elevation", "500"]) == 2
    assert "elevation = 500" in capsys.readouterr().err
