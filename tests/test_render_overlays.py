"""Overviews a reader can read, on llvmpipe: ranges from the data, legends, annotations, framing
of any domain, and ``flowkit render`` without a style."""

from __future__ import annotations

import json

import numpy as np
import pytest
from render_scenes import FACE_ON, straight, style

from flowkit.lines import Lines
from flowkit.render import Band, Camera, ColorMap, LineRenderer, StyleError, render_lines
from flowkit.render.colormaps import colormap_lut
from flowkit.render.legend import legend_image
from flowkit.render.style import style_from_dict

WHITE = (1, 1, 1, 1)


def _plateaus(lo=3.0, hi=7.0, n=90):
    """A line along x whose attribute is lo on its first third, hi on its last, a ramp between."""
    v = np.interp(np.linspace(0, 1, n), [0, 1 / 3, 2 / 3, 1], [lo, lo, hi, hi])
    return straight((-1, 0, 0), (1, 0, 0), n=n, s=v)


def test_range_left_out_spans_the_data_so_its_ends_are_the_colormap_ends():
    lines = _plateaus()
    s = style(Band(ColorMap("viridis", "s"), 4.0), background=WHITE, antialias="none")
    img = render_lines(lines, s, (200, 100), FACE_ON)
    lut = np.rint(colormap_lut("viridis")[:, :3] * 255).astype(int)
    for col, want in ((60, lut[0]), (140, lut[-1])):  # on the plateaus (x = -0.8, 0.8)
        assert np.abs(img[50, col, :3].astype(int) - want).max() <= 1, (col, img[50, col])
    # percentiles: p0..p50 puts the high plateau at the colormap's end too
    half = style(Band(ColorMap("viridis", "s", "p0..p50"), 4.0), background=WHITE,
                 antialias="none")
    with LineRenderer(lines) as r:
        assert r.resolve(half).line_style.bands[0].color.range == pytest.approx((3.0, 5.0), abs=0.1)
        img = r.render(half, (200, 100), FACE_ON)
    assert np.abs(img[50, 125, :3].astype(int) - lut[-1]).max() <= 1


def test_transfer_bounds_cannot_come_from_the_data_and_the_error_says_so():
    doc = {"version": 1, "styles": {"a": {"bands": [{"width": 1}]}},
           "transfer": {"attribute": "s", "ranges": [{"range": "p2..p98", "style": "a"}]}}
    with pytest.raises(StyleError, match=r"range 1: range = 'p2..p98'.*cannot come from the data"):
        style_from_dict(doc)
    with pytest.raises(StyleError, match=r"color.range = 'p2-p98'.*percentiles"):
        style_from_dict({"version": 1, "bands": [
            {"color": {"cmap": "viridis", "attribute": "s", "range": "p2-p98"}}]})


def _bar_row(img, box, lut):
    """(row, first column, last column) of the longest run of pixels in ``box`` matching the
    colormap left to right, or None."""
    x0, y0, x1, y1 = box
    best = None
    for r in range(y0, y1):
        px = img[r, x0:x1, :3].astype(int)
        d = np.abs(px[:, None, :] - lut[None, :, :]).max(axis=2)
        k, err = d.argmin(axis=1), d.min(axis=1)
        ok = err <= 2
        if ok.sum() < 50:
            continue
        cols = np.flatnonzero(ok)
        if (np.all(np.diff(k[cols]) >= 0) and k[cols[0]] <= 3 and k[cols[-1]] >= 252
                and (best is None or cols.size > best[2] - best[1])):
            best = (r, x0 + cols[0], x0 + cols[-1])
    return best


@pytest.mark.parametrize("placement", ["top-left", "bottom-right"])
def test_legend_bar_follows_the_colormap_has_text_and_moves(placement):
    s = style(Band(ColorMap("plasma", "speed", (0.0, 0.3)), 2.0), background=WHITE)
    img, box = legend_image(s, (400, 300), units={"speed": "m/s"}, placement=placement)
    assert img.shape == (300, 400, 4)
    x0, y0, x1, y1 = box
    outside = img.copy()
    outside[y0:y1, x0:x1] = 0
    assert not outside[..., 3].any()  # nothing drawn outside its box
    assert (x0 < 200) == (placement == "top-left") and (y0 < 150) == (placement == "top-left")
    lut = np.rint(colormap_lut("plasma")[:, :3] * 255).astype(int)
    row, c0, c1 = _bar_row(img, box, lut)
    assert c1 - c0 > 0.15 * 400  # the bar, end to end
    ink = (img[..., 3] > 0) & (img[..., :3].astype(int).max(axis=2) < 150)
    assert ink[y0:row - 2, x0:x1].sum() > 30  # title "speed [m/s]" above the bar
    below = row + 1 + np.argmax(~ink[row + 1:y1, c0 + 5])  # the first row under the bar
    assert ink[below + 2:y1, x0:x1].sum() > 30  # tick labels under it


def test_auto_placement_avoids_the_lines():
    s = style(Band(ColorMap("viridis", "s", (0, 1)), 2.0), background=WHITE)
    cover = np.zeros((300, 400), bool)
    cover[:150, :] = True  # lines fill the top half
    _, box = legend_image(s, (400, 300), coverage=cover)
    assert box[1] >= 150
    cover = np.ones((300, 400), bool)
    cover[150:, :200] = False  # only the bottom-left is free
    _, box = legend_image(s, (400, 300), coverage=cover)
    assert box[0] < 200 and box[1] >= 150


def test_overlays_draw_title_time_and_legend_at_output_resolution():
    lines = _plateaus()
    lines.attrs = {"units": json.dumps({"s": "K"}), "snapshot_time": 2000.0, "length_units": "m"}
    doc = {"version": 1, "background": "#ffffff", "supersample": 2,
           "bands": [{"color": {"cmap": "viridis", "attribute": "s"}, "width": 3}],
           "legend": {"placement": "top-left"},
           "annotations": {"title": "Heated room", "scale_bar": True}}
    s = style_from_dict(doc)
    with LineRenderer(lines) as r:
        bare = r.render(s, (320, 200), FACE_ON)
        full = r.render(s, (320, 200), FACE_ON, overlays=True)
    changed = np.abs(full.astype(int) - bare.astype(int)).max(axis=2) > 40
    assert changed[:60, :160].sum() > 50   # legend top-left
    assert changed[:30, 100:220].sum() > 20  # title, top centre
    assert changed[140:, 160:].sum() > 20  # time and scale bar, bottom right


def _box_lines(extent) -> Lines:
    """The 12 edges of a box of ``extent`` centred at the origin, as lines."""
    e = np.asarray(extent, float) / 2
    corners = np.array(np.meshgrid(*[[-1, 1]] * 3, indexing="ij")).reshape(3, -1).T * e
    parts = []
    for i in range(8):
        for j in range(i + 1, 8):
            if np.sum(corners[i] != corners[j]) == 1:
                parts.append(straight(corners[i], corners[j], n=16))
    return Lines.concatenate(parts)


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
@pytest.mark.parametrize("extent", [(1, 1, 1), (0.1, 1, 0.2), (10, 1, 0.5)])
def test_framing_fills_the_image_and_touches_no_edge(extent, projection):
    size = (200, 120)
    s = style(Band((0, 0, 0, 1), 1.5), background=WHITE, antialias="none")
    img = render_lines(_box_lines(extent), s, size, Camera(projection=projection))
    drawn = np.any(img[:, :, :3] < 128, axis=2)
    rows, cols = np.flatnonzero(drawn.any(axis=1)), np.flatnonzero(drawn.any(axis=0))
    assert rows[0] > 0 and cols[0] > 0 and rows[-1] < size[1] - 1 and cols[-1] < size[0] - 1
    span = max((rows[-1] - rows[0] + 1) / size[1], (cols[-1] - cols[0] + 1) / size[0])
    assert span >= 0.8, f"{extent}: drawn span {span:.2f}"
    # centred: perspective looks at the projected box's centre, not the bounds'
    centre = ((cols[0] + cols[-1] + 1) / 2, (rows[0] + rows[-1] + 1) / 2)
    assert centre == pytest.approx((size[0] / 2, size[1] / 2), abs=2.5), centre


def test_named_views_look_along_their_axis():
    lines = _box_lines((2, 1, 0.5))
    s = style(Band((0, 0, 0, 1), 1.5), background=WHITE, antialias="none")
    img = render_lines(lines, s, (200, 120), Camera(view="+z", projection="orthographic"))
    drawn = np.any(img[:, :, :3] < 128, axis=2)
    rows, cols = np.flatnonzero(drawn.any(axis=1)), np.flatnonzero(drawn.any(axis=0))
    # looking along z: a 2 x 1 rectangle, x (the longest) along the image's width
    ratio = (cols[-1] - cols[0]) / (rows[-1] - rows[0])
    assert ratio == pytest.approx(2.0, rel=0.1)
    with pytest.raises(StyleError, match="view = '\\+z' and azimuth"):
        style_from_dict({"version": 1, "bands": [{"width": 1}],
                         "camera": {"view": "+z", "azimuth": 10}})


def _lines_files(tmp_path):
    from flowkit import trace
    from flowkit.fields.analytic import make
    from flowkit.io.lines_h5 import write_lines

    fld = make("abc").to_field(12)
    seeds = [[1.0, 1.0, 1.0], [2.0, 3.0, 1.5]]
    yield write_lines(trace(fld, seeds, attributes=("speed", "time"), max_length=2.0),
                      tmp_path / "speed.h5")
    yield write_lines(trace(fld, seeds, max_length=2.0), tmp_path / "geometry.h5")
    yield write_lines(_plateaus(), tmp_path / "synthetic.h5")
    yield write_lines(Lines.empty(), tmp_path / "empty.h5")


def test_flowkit_render_without_a_style_works_on_every_lines_file(tmp_path, capsys):
    from PIL import Image

    from flowkit.cli import main

    for path in _lines_files(tmp_path):
        out = tmp_path / f"{path.stem}.png"
        if path.stem == "empty":  # nothing to draw: an error, and no picture
            assert main(["render", str(path), "-o", str(out), "--size", "240x160"]) == 2
            assert "nothing to draw: the file holds no line" in capsys.readouterr().err
            assert not out.exists()
            continue
        assert main(["render", str(path), "-o", str(out), "--size", "240x160"]) == 0, path
        img = np.asarray(Image.open(out))
        drawn = np.abs(img[:, :, :3].astype(int) - 255).max(axis=2) > 60
        assert drawn.mean() > 0.01, path
        if path.stem == "speed":  # coloured by speed, with its legend
            lut = np.rint(colormap_lut("viridis")[:, :3] * 255).astype(int)
            assert _bar_row(img, (0, 0, 240, 160), lut) is not None
    no_legend = tmp_path / "bare.png"
    assert main(["render", str(tmp_path / "speed.h5"), "-o", str(no_legend), "--size", "240x160",
                 "--no-legend", "--view", "iso"]) == 0
    lut = np.rint(colormap_lut("viridis")[:, :3] * 255).astype(int)
    assert _bar_row(np.asarray(Image.open(no_legend)), (0, 0, 240, 160), lut) is None


def test_style_files_round_trip_automatic_ranges_legend_and_annotations():
    from flowkit.render.style import dump_style, style_to_dict

    doc = {"version": 1, "legend": {"show": False, "placement": "bottom-left"},
           "annotations": {"title": "T", "time": False, "text": "run 3", "scale_bar": True},
           "camera": {"view": "iso", "fit": "sphere"},
           "bands": [{"color": {"cmap": "viridis", "attribute": "s"},
                      "width": {"attribute": "s", "range": "p5..p95", "min": 1, "max": 3}}]}
    s = style_from_dict(doc)
    assert s.line_style.bands[0].color.range is None
    assert style_from_dict(style_to_dict(s)) == s
    assert "range" not in dump_style(s).split("[[bands]]")[1].split("width")[0]
    for bad, key in (({"legend": {"placement": "middle"}}, "placement"),
                     ({"annotations": {"title": "a\nb"}}, "title"),
                     ({"legend": {"size": 3}}, "unknown key 'size'")):
        with pytest.raises(StyleError, match=key):
            style_from_dict({**doc, **bad})


def test_scale_bar_is_a_round_length_at_the_given_scale_and_keys_show_width_and_styles():
    from flowkit.render import LineStyle, Style, WidthMap
    from flowkit.render.legend import annotation_image, round_down
    from flowkit.render.style import Transfer, TransferRange

    s = style(Band((0, 0, 0, 1), 1.0), background=WHITE)
    img, box = annotation_image((400, 200), s, world_per_pixel=0.02, length_units="m")
    ink = (img[..., 3] > 0) & (img[..., :3].max(axis=2) < 100)
    runs = [np.flatnonzero(r) for r in ink]
    longest = max(runs, key=len)
    assert round_down(0.2 * 400 * 0.02) == 1.0 and len(longest) == pytest.approx(50, abs=1)
    assert longest[-1] - longest[0] + 1 == len(longest)  # one solid bar
    assert ink[box[1]:box[3], box[0]:box[2]].sum() > len(longest) * 3 + 30  # and its label
    # width key and transfer styles: a wedge and one swatch per named style
    two = Style(styles={"a": LineStyle((Band(ColorMap("viridis", "s", (0, 1)),
                                             WidthMap("s", (0, 1), 1, 4)),)),
                        "b": LineStyle((Band((1, 0, 0, 1), 1.0),))},
                transfer=Transfer("d", (TransferRange((0, 1), "a"), TransferRange((1, 2), "b"))))
    leg, box = legend_image(two, (400, 300), units={"d": "m"}, placement="top-left")
    red = (leg[..., 0] > 200) & (leg[..., 1] < 60) & (leg[..., 2] < 60) & (leg[..., 3] > 0)
    assert red.sum() > 20  # style b's swatch
    wedge_rows = (leg[..., :3].max(axis=2) < 60) & (leg[..., 3] > 0)
    cols = wedge_rows.sum(axis=0)
    assert cols.max() > 3  # the wedge's wide end is several rows tall


def _top_heavy() -> Lines:
    """Horizontal lines over the upper half of their bounds, one short line low left."""
    parts = [straight((-1, 0, z), (1, 0, z), n=20, s=z) for z in np.linspace(0.15, 0.95, 9)]
    return Lines.concatenate(parts + [straight((-1, 0, -0.9), (-0.5, 0, -0.9), n=5, s=0.0)])


def test_title_and_text_go_where_they_cover_the_fewest_lines():
    doc = {"version": 1, "background": "#ffffff", "antialias": "none",
           "bands": [{"color": "#000000", "width": 2}], "legend": {"show": False},
           "annotations": {"title": "Cavity", "text": "run 3", "time": False}}
    s = style_from_dict(doc)
    cam = Camera(azimuth=-90, elevation=0, up=(0, 0, 1), projection="orthographic")  # filled
    with LineRenderer(_top_heavy()) as r:
        bare = r.render(s, (320, 200), cam)
        full = r.render(s, (320, 200), cam, overlays=True)
    changed = np.abs(full.astype(int) - bare.astype(int)).max(axis=2) > 40
    lines_px = np.any(bare[:, :, :3] < 128, axis=2)
    near = np.zeros_like(lines_px)  # the lines and a few pixels around them
    for dy in range(-4, 5):
        near |= np.roll(lines_px, dy, axis=0)
    assert not (changed & near).any()  # no overlay over (or touching) a line
    assert changed[:100].sum() == 0  # the title left the top, where the lines are
    assert changed[150:, 100:220].sum() > 20  # for the bottom centre
    assert changed[150:, :60].sum() > 20  # the text: the free bottom corner


def test_overlays_outside_widen_the_picture_and_cover_no_line():
    lines = _plateaus()
    lines.attrs = {"snapshot_time": 2000.0}
    doc = {"version": 1, "background": "#ffffff",
           "bands": [{"color": {"cmap": "viridis", "attribute": "s"}, "width": 3}],
           "legend": {"placement": "outside"}, "annotations": {"title": "Heated room"}}
    s = style_from_dict(doc)
    with LineRenderer(lines) as r:
        bare = r.render(s, (320, 200), FACE_ON)
        full = r.render(s, (320, 200), FACE_ON, overlays=True)
    H, W = full.shape[:2]
    assert W > 320 + 60 and H > 200  # a margin right for the legend, top and bottom for text
    top = next(y for y in range(H) if np.array_equal(full[y:y + 200, :320], bare)) \
        if any(np.array_equal(full[y:y + 200, :320], bare) for y in range(H - 199)) else None
    assert top is not None and top > 0  # the picture itself, untouched by any overlay
    lut = np.rint(colormap_lut("viridis")[:, :3] * 255).astype(int)
    assert _bar_row(full, (320, 0, W, H), lut) is not None  # the colour bar in the margin
    assert np.abs(full[:top, :320, :3].astype(int) - 255).max() > 60  # the title above


def test_tick_labels_centred_on_their_ticks_never_touch():
    from flowkit.render.legend import fitting_ticks

    def length(text):  # 12 pixels a character: "300.2" .. "300.8" would touch
        return 12.0 * len(text)

    ticks, names = fitting_ticks(300.02, 300.93, 265, length, 6)
    at = [(t - 300.02) / (300.93 - 300.02) * 265 for t in ticks]
    assert len(ticks) >= 2
    for i in range(len(ticks) - 1):
        assert at[i + 1] - at[i] >= (length(names[i]) + length(names[i + 1])) / 2 + 6, names
