"""Pixel tests of the line-style renderer on llvmpipe (headless EGL)."""

from __future__ import annotations

import moderngl
import numpy as np
import pytest
from render_scenes import FACE_ON, project, straight, style

from flowkit.lines import Lines
from flowkit.render import Band, Camera, ColorMap, LineRenderer, WidthMap, render_lines
from flowkit.render.colormaps import TEXELS, colormap_lut, colormap_texture
from flowkit.render.context import default_context

RED, BLUE, WHITE, BLACK, GREY = (1, 0, 0, 1), (0, 0, 1, 1), (1, 1, 1, 1), (0, 0, 0, 1), (.5, .5, .5, 1)
SIZE = (200, 100)


def rgb(img, row, col):
    return tuple(int(c) for c in img[row, col, :3])


def test_two_bands_put_colours_at_expected_offsets():
    lines = straight((-1, 0, 0), (1, 0, 0))
    centre_row = project(lines.bounds(), FACE_ON, SIZE, [0, 0, 0])[0, 1]
    assert centre_row == pytest.approx(50.0)
    two = style(Band(RED, 3.0), Band(BLUE, 2.0), background=WHITE, antialias="none")
    img = render_lines(lines, two, SIZE, FACE_ON)
    col = img[:, 100, :3].astype(int)
    # row r covers offsets (r - 50, r + 1 - 50); its centre is at r + 0.5 - 50
    for r in range(SIZE[1]):
        off = abs(r + 0.5 - centre_row)
        want = (255, 0, 0) if off < 3 else (0, 0, 255) if off < 5 else (255, 255, 255)
        assert tuple(col[r]) == want, f"row {r} (offset {off}): {tuple(col[r])} != {want}"
    # with MSAA and band smoothing, band centres keep their pure colours
    img = render_lines(lines, style(Band(RED, 3.0), Band(BLUE, 2.0), background=WHITE), SIZE, FACE_ON)
    for r, want in [(48, (255, 0, 0)), (51, (255, 0, 0)), (45, (0, 0, 255)), (54, (0, 0, 255)),
                    (43, (255, 255, 255)), (56, (255, 255, 255))]:
        assert rgb(img, r, 100) == want


def _crossing(depth_gap, offset, projection):
    """Front line along x at y=0 (core black, white halo with a depth offset), back line along z
    at y=depth_gap; returns the image and pixel coords of the crossing."""
    front = straight((-1, 0, 0), (1, 0, 0))
    back = straight((0.3, depth_gap, -1), (0.3, depth_gap, 1))
    lines = Lines.concatenate([back, front])  # back drawn first: the depth test must decide
    cam = Camera(azimuth=-90, elevation=0, projection=projection, distance=6.0,
                 target=(0.0, 0.0, 0.0), fov=30)
    s = style(Band(BLACK, 2.0), Band(WHITE, 4.0, depth_offset=offset), background=GREY,
              antialias="none")
    img = render_lines(lines, s, (160, 160), cam)
    x, y = project(lines.bounds(), cam, (160, 160), [[0.3, 0, 0]])[0]
    return img, int(x), int(y)


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
def test_halo_cuts_back_line_only_when_depth_gap_exceeds_offset(projection):
    # gap 1.0 > offset 0.8: the front halo is nearer than the back line's core -> white gap
    img, x, y = _crossing(1.0, 0.8, projection)
    assert rgb(img, y, x) == (0, 0, 0)  # front core
    above = [rgb(img, y - d, x) for d in (3, 4)]  # inside the front halo, on the back line
    assert above == [(255, 255, 255)] * 2
    assert rgb(img, y - 12, x) == (0, 0, 0)  # back line's core away from the crossing
    # gap 1.0 < offset 1.2: the halo lies behind the back line -> the back core shows through
    img, x, y = _crossing(1.0, 1.2, projection)
    assert [rgb(img, y - d, x) for d in (3, 4)] == [(0, 0, 0)] * 2
    # same depth: lines merge, the back line's core is never cut
    img, x, y = _crossing(0.0, 0.05, projection)
    assert [rgb(img, y - d, x) for d in (3, 4)] == [(0, 0, 0)] * 2
    # ...while the halo is still drawn beside the line where there is no other line
    assert rgb(img, y - 4, x - 40) == (255, 255, 255)


def _column_width(img, col, background):
    return int(np.sum(np.any(img[:, col, :3] != background, axis=1)))


def test_width_mapping_is_linear_in_attribute():
    values = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
    parts = [straight((-1, 0, z), (1, 0, z), v=v) for z, v in zip([-1.6, -0.8, 0, 0.8, 1.6], values)]
    lines = Lines.concatenate(parts)
    s = style(Band(BLACK, WidthMap("v", (0.0, 1.0), 1.0, 5.0)), background=WHITE, antialias="none")
    img = render_lines(lines, s, (200, 400), FACE_ON)
    rows = project(lines.bounds(), FACE_ON, (200, 400), [[0, 0, z] for z in [-1.6, -0.8, 0, .8, 1.6]])
    widths = []
    for (_, r) in rows:
        band = img[int(r) - 15:int(r) + 15, 100, :3]
        widths.append(int(np.sum(np.any(band != 255, axis=1))))
    expected = 2 * (1 + 4 * values)  # both sides
    np.testing.assert_allclose(widths, expected, atol=1)
    slope = np.polyfit(values, widths, 1)[0]
    assert slope == pytest.approx(8.0, abs=0.5)


@pytest.mark.parametrize("name", ["viridis", "turbo", "gray"])
def test_colormap_texture_gives_the_lut_colour_within_one_level(name):
    # 8-bit texels read with nearest filtering at the shaders' coordinate (the texel nearest to
    # t (TEXELS - 1)) stand for the float LUT, linear between its entries
    ctx = default_context()
    with ctx:
        tex = colormap_texture(ctx, name)
        assert tex.filter == (moderngl.NEAREST, moderngl.NEAREST)
        texels = np.frombuffer(tex.read(), np.uint8).reshape(-1, 4).astype(float)
    lut = colormap_lut(name)
    t = np.linspace(0.0, 1.0, 100001)
    want = np.stack([np.interp(t * (len(lut) - 1), np.arange(len(lut)), lut[:, c])
                     for c in range(4)], axis=1) * 255
    got = texels[np.floor(t * (TEXELS - 1) + 0.5).astype(int)]
    assert np.abs(got - want).max() <= 0.75


def test_colormapped_band_shows_colormap_in_attribute_order():
    t = np.linspace(0, 1, 200)
    lines = straight((-1, 0, 0), (1, 0, 0), n=200, s=t)
    s = style(Band(ColorMap("viridis", "s", (0.0, 1.0)), 4.0), background=WHITE)
    img = render_lines(lines, s, SIZE, FACE_ON)
    lut = colormap_lut("viridis")
    cols = np.arange(55, 146, 10)
    xs = project(lines.bounds(), FACE_ON, SIZE, [[-1, 0, 0], [1, 0, 0]])[:, 0]
    for c in cols:
        frac = (c + 0.5 - xs[0]) / (xs[1] - xs[0])  # attribute value under the pixel centre
        want = np.interp(frac * 255, np.arange(256), lut[:, 0]), np.interp(
            frac * 255, np.arange(256), lut[:, 1]), np.interp(frac * 255, np.arange(256), lut[:, 2])
        got = img[50, c, :3] / 255
        np.testing.assert_allclose(got, want, atol=3 / 255, err_msg=f"column {c}")
    # reversed range reverses the colours
    s = style(Band(ColorMap("viridis", "s", (1.0, 0.0)), 4.0), background=WHITE)
    rev = render_lines(lines, s, SIZE, FACE_ON)
    np.testing.assert_allclose(rev[50, 60, :3].astype(int), img[50, 139, :3].astype(int), atol=3)


def test_world_units_scale_with_zoom_and_pixel_units_do_not():
    lines = straight((-1, 0, 0), (1, 0, 0))
    world = style(Band(BLACK, 0.1), units="world", background=WHITE, antialias="none")
    pix = style(Band(BLACK, 3.0), background=WHITE, antialias="none")
    for zoom in (1.0, 2.0):
        cam = Camera(azimuth=-90, elevation=0, projection="orthographic", zoom=zoom,
                     fit="sphere")
        px_per_unit = 50 * zoom  # half-height 1/zoom over 50 pixels
        assert _column_width(render_lines(lines, world, SIZE, cam), 100, 255) == pytest.approx(
            2 * 0.1 * px_per_unit, abs=1)
        assert _column_width(render_lines(lines, pix, SIZE, cam), 100, 255) == 6


def test_supersampling_keeps_pixel_widths_and_transparent_background():
    lines = straight((-1, 0, 0), (1, 0, 0))
    s = style(Band(RED, 3.0), supersample=2, background=None)
    img = render_lines(lines, s, SIZE, FACE_ON)
    assert img.shape == (100, 200, 4)
    assert img[5, 5, 3] == 0 and img[50, 100, 3] == 255
    assert int(np.sum(img[:, 100, 3] > 127)) == 6


def test_only_the_attributes_the_style_reads_are_uploaded():
    lines = straight((-1, 0, 0), (1, 0, 0), p=1.0, q=2.0, r=3.0)
    with LineRenderer(lines) as r:
        r.render(style(Band(ColorMap("viridis", "q", (0, 4)), 2.0)), (64, 32), FACE_ON)
        assert r.uploaded_attributes() == ["q"]
        r.render(style(Band(BLACK, 2.0)), (64, 32), FACE_ON)
        assert r.uploaded_attributes() == ["q"]


def test_perspective_fit_shows_all_lines_and_line_ends_join():
    t = np.linspace(0, 4 * np.pi, 400)
    lines = Lines(np.stack([np.cos(t), np.sin(t), t / 6], 1), [0, 400])
    img = render_lines(lines, style(Band(BLACK, 2.0), background=WHITE), (120, 120), Camera())
    ink = np.any(img[:, :, :3] < 128, axis=2)
    assert ink.sum() > 400
    assert not ink[0].any() and not ink[-1].any() and not ink[:, 0].any() and not ink[:, -1].any()
    # a smooth curve drawn as a continuous strip: the ink is one connected blob per visible run,
    # no gaps at joins -> each row crossing the helix has few separate runs
    runs = [np.count_nonzero(np.diff(row.astype(int)) == 1) for row in ink]
    assert max(runs) <= 4


def test_renderers_on_two_contexts_do_not_mix_gl_objects():
    from flowkit.render import create_context

    lines = straight((-1, 0, 0), (1, 0, 0), n=50, s=np.linspace(0, 1, 50))
    viridis = style(Band(ColorMap("viridis", "s", (0.0, 1.0)), 4.0))
    first = render_lines(lines, viridis, SIZE, FACE_ON)
    other = create_context("egl")
    try:
        gray = render_lines(lines, style(Band(ColorMap("gray", "s", (0.0, 1.0)), 4.0)), SIZE,
                            FACE_ON, ctx=other)
        again = render_lines(lines, viridis, SIZE, FACE_ON)  # default context once more
    finally:
        other.release()
    assert not np.array_equal(first, gray)
    np.testing.assert_array_equal(again, first)


@pytest.mark.parametrize("strips", ["vertex", "geometry"])
def test_attributes_follow_a_cubic_between_drawn_points(strips):
    # 7 vertices of a curved attribute on a straight line, every one drawn: the colour between
    # them follows the PCHIP cubic through their values and slopes (what the level of detail
    # measures against), not the straight interpolation between them
    from flowkit.render.simplify import arc_parameter, hermite, slopes
    n = 7
    x = np.linspace(-1, 1, n)
    v = 0.5 + 0.45 * np.sin(2.2 * x)
    lines = straight((-1, 0, 0), (1, 0, 0), n=n, v=v)
    s = style(Band(ColorMap("gray", "v", (0.0, 1.0)), 4.0), background=WHITE, antialias="none")
    with LineRenderer(lines, tolerance=0.0, strips=strips) as r:
        img = r.render(s, SIZE, FACE_ON)
        assert r.prepare(s)[0].hermite == (0,)
    st, en = np.array([0]), np.array([n])
    pts = lines.points
    arc = arc_parameter(pts, st, en)
    m = slopes(v, arc, st, en)
    xs = project(lines.bounds(), FACE_ON, SIZE, [[-1, 0, 0], [1, 0, 0]])[:, 0]
    worst_linear = 0.0
    for c in range(int(xs[0]) + 2, int(xs[1]) - 1):
        at = (c + 0.5 - xs[0]) / (xs[1] - xs[0]) * arc[-1]  # arc under the pixel centre
        i = min(np.searchsorted(arc, at) - 1, n - 2)
        want = 255 * hermite(v, m, arc, i, i + 1, at)
        assert abs(int(img[50, c, 0]) - want) <= 2.5, (c, img[50, c, 0], want)
        worst_linear = max(worst_linear, abs(255 * np.interp(at, arc, v) - want))
    assert worst_linear > 4  # the cubic is not the straight interpolation here


def test_attributes_linear_along_the_arc_skip_the_cubic():
    n = 50
    t = np.linspace(0, 1, n)
    lines = straight((-1, 0, 0), (1, 0, 0), n=n, lin=3 * t + 1, sq=t**2)
    with LineRenderer(lines) as r:
        flags, _ = r.prepare(style(Band(ColorMap("gray", "lin", (0.0, 4.0)), 4.0)))
        assert flags.hermite == ()
        flags, _ = r.prepare(style(Band(ColorMap("gray", "sq", (0.0, 1.0)), 4.0)))
        assert flags.hermite == (0,)
