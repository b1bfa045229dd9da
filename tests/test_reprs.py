"""Trace options and styles print as a few readable lines: the options that differ from their
defaults (so a default one is a single line), a style's bands with their colour and width
mappings and ranges, its transfer function and the settings it changes."""

import pytest

from flowkit.integrate.options import TraceOptions
from flowkit.render.camera import Camera
from flowkit.render.renderer import default_style
from flowkit.render.style import (
    Band,
    ColorMap,
    Legend,
    LineStyle,
    Pattern,
    Shape,
    Style,
    Transfer,
    TransferRange,
    WidthMap,
)


def test_default_trace_options_are_one_short_line():
    assert repr(TraceOptions()) == ("<TraceOptions: method dopri5, rtol 1e-06; the other "
                                    "options at their defaults>")
    assert repr(TraceOptions(method="rk45")) == repr(TraceOptions())  # an alias is the method


def test_trace_options_show_what_differs_as_keywords():
    opts = TraceOptions(method="rk4", rtol=(1e-6, 1e-6, 1e-8), max_length=20.0,
                        direction="both", attributes="speed,T", memory="4GB", max_steps=5000,
                        spacing=0.01)
    text = repr(opts)
    lines = text.splitlines()
    assert lines[0] == "<TraceOptions: method rk4, rtol (1e-06, 1e-06, 1e-08)"
    body = " ".join(lines[1:])
    for part in ("max_steps=5000", "max_length=20.0", "direction='both'", "spacing=0.01",
                 "attributes=('speed', 'T')", "memory='4 GB'"):
        assert part in body, part
    # only what differs: the defaults stay out, and every row is short
    assert "atol" not in text and "cell_aware" not in text and "progress" not in text
    assert 2 <= len(lines) <= 4 and max(map(len, lines)) <= 90
    assert opts._repr_html_() == "<pre>" + text.replace("'", "&#x27;").replace(
        "<", "&lt;").replace(">", "&gt;") + "</pre>"


def test_an_unregistered_method_says_so():
    from flowkit.integrate.methods import Method

    heun = Method.from_butcher("heun", [0.0, 1.0], [[0.0, 0.0], [1.0, 0.0]], [0.5, 0.5],
                               [1.0, 0.0], order=2, err_order=1)
    assert repr(TraceOptions(method=heun)).startswith("<TraceOptions: method heun (unregistered), rtol")


def test_trace_options_keywords_rebuild_them():
    opts = TraceOptions(max_length=2.5, direction="backward", stagnation_rel=1e-3, count=40)
    body = repr(opts).split("\n", 1)[1].rstrip(">")
    assert eval(f"TraceOptions({body})") == opts


def test_the_default_style_shows_its_bands():
    text = repr(default_style(["speed"]))
    assert text.splitlines() == [
        "<Style: 1 line style, widths in pixels, reads speed",
        "  default:",
        "    band 0: colour viridis of speed over the data's range, width 2.5",
        "    band 1: colour #000000, width 1.5, set back 1/50z",
        "  background #ffffff, antialias msaa x4>"]
    assert default_style([])._repr_html_().startswith("<pre>&lt;Style: 1 line style")


def test_a_style_shows_mappings_ranges_transfer_and_changed_settings():
    core = Band(ColorMap("plasma", "T", (299.0, 301.5)),
                WidthMap("speed", "p5..p95", 1.0, 4.0), shape=Shape("arrow", "time", 0.5))
    halo = Band((0.0, 0.0, 0.0, 0.5), 1.25, depth_offset="1/200z",
                pattern=Pattern((1.0, 0.0, 0.0, 1.0), length=0.2))
    style = Style(styles={"hot": LineStyle((core, halo)),
                          "cold": LineStyle((Band((0.1, 0.2, 0.3, 1.0), 1.0),)),
                          "spare": LineStyle((Band(),))},
                  transfer=Transfer("T", (TransferRange((299.0, 300.0), "cold"),
                                          TransferRange((300.0, 301.0), "hot"),
                                          TransferRange((301.0, 302.0), None)), blend=0.25),
                  units="world", background=None, supersample=2,
                  camera=Camera(view="+x", zoom=1.5), legend=Legend(show=False))
    lines = repr(style).splitlines()
    assert lines[0] == "<Style: 3 line styles, widths in world, reads T, speed, time, arc_length"
    assert lines[1] == "  hot:"
    assert lines[2] == ("    band 0: colour plasma of T over [299, 301.5], width 1..4 from speed "
                        "over the data's percentiles p5..p95, shape arrow every 0.5 of time")
    assert lines[3] == ("    band 1: colour rgba(0, 0, 0, 0.5), width 1.25, set back 1/200z, "
                        "pattern #ff0000 every 0.2 of arc_length")
    assert lines[4] == "  cold:" and lines[5].startswith("    band 0: colour rgba(0.1, 0.2, 0.3")
    assert lines[6] == "  spare: (drawn by no range)"
    assert lines[8] == ("  transfer on T: [299, 300) cold, [300, 301) hot, [301, 302) discarded, "
                        "blend 0.25")
    assert lines[9] == ("  background transparent, antialias msaa x4, supersample 2, "
                        "camera zoom=1.5 view='+x', legend show=False>")


@pytest.mark.parametrize("name", ["halo", "plain", "speed_colormap_halo", "temperature_width"])
def test_example_styles_print_in_a_few_lines(name):
    from pathlib import Path

    from flowkit.render.style import load_style

    style = load_style(Path(__file__).parents[1] / "examples" / "styles" / f"{name}.toml")
    text = repr(style)
    assert 4 <= len(text.splitlines()) <= 8 and "band 0:" in text
    for a in style.attributes():
        assert a in text.splitlines()[0]
