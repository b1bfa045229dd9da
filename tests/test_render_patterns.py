"""Directional colour patterns (paper 3.4): f_d(x, b) = ((x/l + a b^c) mod 1) - w picks one of
two colours.  On a straight face-on line: the period in pixels is l (arc-length x); with
integration-time x the period grows with speed as predicted; the stripe boundary's lateral
slope follows a and c; the phase moves the stripes; the width is untouched."""

from __future__ import annotations

import numpy as np
import pytest
from line_probe import Probe, half_width, transitions
from render_scenes import style

from flowkit.render import Band, ColorMap, StyleError, load_style
from flowkit.render.colormaps import colormap_lut
from flowkit.render.shader_build import build_sources, shader_flags
from flowkit.render.style import Pattern

YELLOW, BLUE, WHITE = (1, 1, 0, 1), (0, 0, 1, 1), (1, 1, 1, 1)


def second_colour_share(img, row):
    """0 where the pixel is yellow (first colour), 1 where blue (second), linear between."""
    return 1.0 - img[row, :, 0].astype(float) / 255.0


def _pattern_style(pattern, width=6.0, **kw):
    return style(Band(YELLOW, width, pattern=pattern), background=WHITE, **kw)


@pytest.mark.parametrize("length", [0.2, 0.37])
def test_period_in_pixels_equals_length_for_arc_length(length):
    n = 101
    p = Probe(n=n, arc_length=np.linspace(0.0, 2.0, n))
    img = p.render(_pattern_style(Pattern(BLUE, "arc_length", length, fraction=0.5)))
    row = int(p.centre)
    t = transitions(second_colour_share(img, row))
    t = t[(t > p.c0 + 2) & (t < p.c0 + 2 * p.px_per_world - 2)]
    assert len(t) >= int(2.0 / length) - 1
    period = np.diff(t)
    want = length * p.px_per_world
    assert np.abs(period - want).max() < 0.5, (period, want)
    # and the boundaries sit where x / l crosses w (mod 1): at x = l (k + w)
    x = p.world_x(t - 0.5) + 1.0  # arc length under each boundary
    k = np.round(x / length - 0.5)
    assert np.abs((x - length * (k + 0.5)) * p.px_per_world).max() < 0.5
    # the pattern leaves the width alone
    assert all(half_width(img, c) == 6.0 for c in p.columns()[::7])


def test_integration_time_period_grows_with_speed():
    # speed 0.5 on x < 0, 1.5 on x > 0: time = integral of ds / v along the line
    n = 401
    x = np.linspace(-1.0, 1.0, n)
    v = np.where(x < 0, 0.5, 1.5)
    dt = np.diff(x) / (0.5 * (v[:-1] + v[1:]))
    dt[n // 2 - 1] = (x[n // 2] - x[n // 2 - 1]) / 0.5  # the vertex at x = 0 ends the slow part
    time = np.r_[0.0, np.cumsum(dt)]
    p = Probe(n=n, time=time)
    lt = 0.15  # pattern length in time units: period in arc length = lt * speed
    img = p.render(_pattern_style(Pattern(BLUE, "time", lt, fraction=0.5)))
    t = transitions(second_colour_share(img, int(p.centre)))
    xs = p.world_x(t - 0.5)
    slow, fast = np.diff(t[xs < -0.02]), np.diff(t[xs > 0.25])
    assert len(slow) >= 5 and len(fast) >= 2
    assert np.abs(slow - lt * 0.5 * p.px_per_world).max() < 0.6
    assert np.abs(fast - lt * 1.5 * p.px_per_world).max() < 0.6
    assert np.mean(fast) / np.mean(slow) == pytest.approx(3.0, rel=0.03)


@pytest.mark.parametrize("a, c", [(0.5, 1.0), (1.0, 2.0), (-0.6, 0.5)])
def test_stripe_slope_follows_a_and_c(a, c):
    n = 101
    p = Probe(n=n, arc_length=np.linspace(0.0, 2.0, n))
    length, w_px = 0.4, 24.0
    img = p.render(_pattern_style(Pattern(BLUE, "arc_length", length, a, c, 0.5), width=w_px,
                                  antialias="none"))
    mid = p.c0 + p.px_per_world  # a boundary near the line's middle at lateral position 0
    def expect(row):  # boundary shift at lateral position b: x/l + a b^c = const
        b = abs(row + 0.5 - p.centre) / w_px
        return -length * a * b**c * p.px_per_world

    t0 = transitions(second_colour_share(img, int(p.centre)))
    ref = t0[np.argmin(np.abs(t0 - mid))] - expect(int(p.centre))  # the boundary at b = 0
    shifts, want = [], []
    for drow in range(1, int(w_px) - 1):
        for row in (int(p.centre) - drow, int(p.centre) + drow - 1):  # both mirrored sides
            t = transitions(second_colour_share(img, row))
            shifts.append(t[np.argmin(np.abs(t - (ref + expect(row))))] - ref)
            want.append(expect(row))
    err = np.abs(np.array(shifts) - np.array(want))
    assert err.max() <= 1.0, (err.max(), shifts[int(err.argmax())], want[int(err.argmax())])
    assert np.ptp(want) > 10  # the slope is many pixels: the test can tell a and c apart


def test_phase_moves_the_stripes_by_a_fraction_of_the_period():
    n = 101
    p = Probe(n=n, arc_length=np.linspace(0.0, 2.0, n))
    pat = Pattern(BLUE, "arc_length", 0.4, fraction=0.5)
    t0 = transitions(second_colour_share(p.render(_pattern_style(pat)), int(p.centre)))
    t1 = transitions(second_colour_share(p.render(_pattern_style(pat, phase=0.25)),
                                         int(p.centre)))
    # s + phase: the boundary at x/l + 0.25 = w comes a quarter period earlier (upstream)
    shift = 0.25 * 0.4 * p.px_per_world
    d = [t1[np.argmin(np.abs(t1 - (x - shift)))] - (x - shift) for x in t0[2:-2]]
    assert np.abs(d).max() < 0.5


def test_colormapped_pattern_colours():
    n = 101
    T = np.linspace(0.0, 1.0, n)
    p = Probe(n=n, arc_length=np.linspace(0.0, 2.0, n), T=T)
    s = style(Band(ColorMap("viridis", "T", (0, 1)), 6.0,
                   pattern=Pattern((0, 0, 0, 1), "arc_length", 0.5, fraction=0.7)),
              background=WHITE, antialias="none")
    img = p.render(s)
    row = img[int(p.centre), :, :3].astype(int)
    lut = colormap_lut("viridis")
    cols = p.columns()
    s_frac = np.mod(p.attr_at("arc_length", cols) / 0.5, 1.0)
    first = cols[s_frac < 0.65]  # well inside the colormapped part (fraction 0.7)
    second = cols[s_frac > 0.75]
    assert np.all(row[second] == 0)
    want = lut[np.clip(np.rint(p.attr_at("T", first) * 255).astype(int), 0, 255), :3] * 255
    assert np.abs(row[first] - want).max() <= 3


def test_shader_has_pattern_code_only_when_used():
    plain = build_sources(shader_flags(style(Band(YELLOW, 2.0)), True))["fragment_shader"]
    for word in ("pattern_coverage", "u_pat", "u_pcolor", "fw_attr", "u_phase"):
        assert word not in plain
    pat = build_sources(shader_flags(style(
        Band(YELLOW, 2.0), Band(BLUE, 1.0, pattern=Pattern(YELLOW, "time", 2.0))), True))
    frag = pat["fragment_shader"]
    assert "uniform vec4 u_pat1;" in frag and "u_pat0" not in frag
    assert frag.count("pattern_coverage(") == 2  # its definition and the one band using it
    assert "shape_" not in frag and "u_pcmap" not in frag



@pytest.mark.parametrize("a, c, pow_, lateral", [(0.0, 2.0, False, False), (0.5, 1.0, False, True),
                                                 (0.5, 2.0, True, True)])
def test_pattern_lateral_term_compiled_only_as_far_as_slope_and_curve_need(a, c, pow_, lateral):
    # no slant (a = 0): no lateral term at all; c = 1: linear, no pow (llvmpipe pays for a pow
    # on every fragment of the strip)
    frag = build_sources(shader_flags(style(
        Band(BLUE, 1.0, pattern=Pattern(YELLOW, "time", 2.0, a, c))), True))["fragment_shader"]
    assert ("pow(" in frag) == pow_
    assert ("p.y *" in frag) == lateral and ("fw_b /" in frag) == lateral


BAD = {
    "no_color": ('pattern = { length = 2 }', ["missing key 'color'"]),
    "fraction": ('pattern = { color = "#000000", fraction = 1.5 }', ["pattern.fraction = 1.5", "<= 1"]),
    "curve": ('pattern = { color = "#000000", curve = 0 }', ["pattern.curve = 0", "> 0"]),
    "length": ('pattern = { color = "#000000", length = -1 }', ["pattern.length = -1"]),
    "cmap": ('pattern = { color = { cmap = "nope_x", attribute = "T", range = [0, 1] } }',
             ["pattern.color.cmap = 'nope_x'"]),
    "key": ('pattern = { color = "#000000", slant = 1 }', ["unknown key 'slant'", "slope"]),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_pattern_gets_its_error(tmp_path, case):
    line, parts = BAD[case]
    path = tmp_path / "p.toml"
    path.write_text(f"version = 1\n[[bands]]\nwidth = 2\n{line}\n")
    with pytest.raises(StyleError) as e:
        load_style(path)
    for part in [str(path), "band 1", *parts]:
        assert part in str(e.value), f"{part!r} not in {e.value}"


# -- animation --------------------------------------------------------------------------------
def test_cli_frames_write_numbered_pngs_and_a_looping_gif(tmp_path, capsys):
    from PIL import Image

    from flowkit.cli import main
    from flowkit.io.lines_h5 import write_lines

    n = 101
    p = Probe(n=n, arc_length=np.linspace(0.0, 2.0, n))
    h5 = tmp_path / "line.h5"
    write_lines(p.lines, h5)
    sfile = tmp_path / "s.toml"
    sfile.write_text('version = 1\nantialias = "none"\n[camera]\nazimuth = -90\nelevation = 0\n'
                     'projection = "orthographic"\nfit = "sphere"\nzoom = 2.9\n[[bands]]\ncolor = "#ffff00"\n'
                     'width = 6\npattern = { color = "#0000ff", length = 0.4 }\n')
    args = ["render", str(h5), "--style", str(sfile), "--size", "400x120", "--frames", "4"]
    assert main([*args, "-o", str(tmp_path / "f.png")]) == 0
    files = sorted(tmp_path.glob("f_*.png"))
    assert [f.name for f in files] == [f"f_{k:04d}.png" for k in range(4)]
    rows = [second_colour_share(np.asarray(Image.open(f)), int(p.centre)) for f in files]
    t = [transitions(r) for r in rows]
    # frame k is shifted upstream by k/4 of the period (0.4 world units)
    step = 0.25 * 0.4 * p.px_per_world
    for k in (1, 2, 3):
        assert np.abs([t[k][np.argmin(np.abs(t[k] - (x - k * step)))] - (x - k * step)
                       for x in t[0][2:-2]]).max() < 0.6
    assert main([*args, "-o", str(tmp_path / "a.gif"), "--fps", "10"]) == 0
    gif = Image.open(tmp_path / "a.gif")
    assert gif.n_frames == 4 and gif.info["duration"] == 100 and gif.info["loop"] == 0
    assert not list(tmp_path.glob(".*tmp*"))
    # nothing to move, or an unknown format: one clear line
    still = tmp_path / "still.toml"
    still.write_text('version = 1\n[[bands]]\nwidth = 2\n')
    assert main(["render", str(h5), "--style", str(still), "--frames", "3", "-o",
                 str(tmp_path / "x.gif")]) == 2
    assert "no band 'shape' or 'pattern'" in capsys.readouterr().err
    assert main([*args, "-o", str(tmp_path / "x.avi")]) == 2
    assert "-o" in capsys.readouterr().err


def test_gif_frames_share_one_background(tmp_path):
    """A rendered animation of many colours on white: every frame's background is the same
    255 white (a background that changes after the first frame flickers as the GIF loops)."""
    from PIL import Image
    from render_scenes import helices, style

    from flowkit.render import Band, ColorMap, LineRenderer
    from flowkit.render.animate import render_frames, write_animation
    from flowkit.render.style import Shape

    s = style(Band(ColorMap("viridis", "speed"), 3.0, shape=Shape("arrow", "arc", 0.1)),
              Band((0, 0, 0, 1), 1.0), background=(1, 1, 1, 1), supersample=2)
    with LineRenderer(helices()) as r:
        frames = list(render_frames(r, s, 4, (200, 120), None, False))
    write_animation(iter(frames), tmp_path / "a.gif", 4, 10.0)
    gif = Image.open(tmp_path / "a.gif")
    for k in range(4):
        gif.seek(k)
        rgb = np.asarray(gif.convert("RGB"))
        assert np.all(rgb[(frames[k][:, :, :3] == 255).all(axis=2)] == 255), k
