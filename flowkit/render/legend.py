"""Legends and annotations drawn over a rendered picture, as RGBA images any caller composites.

Entry points (each returns an (H, W, 4) uint8 RGBA image of the picture's size, transparent
except where it draws, plus the box it occupies, so the CLI, scenes and an interactive viewer
composite the same pixels):

- ``legend_image(style, size, ...)``: for a style whose ranges are numbers (``LineRenderer.
  resolve``), a colour bar per colour-mapped attribute (name, units, ticks at round numbers), a
  width key per width-mapped attribute, and for a transfer function its named styles and their
  ranges, stacked in one panel in a corner.
- ``annotation_image(size, ...)``: title, the snapshot's time, free text and a scale bar.
- ``composite(image, overlay)``: ``overlay`` over ``image`` (alpha "over").

Text is Pillow's own scalable font (``ImageFont.load_default(size=...)``, Pillow >= 10.1), so no
system font is needed; everything is drawn at the output's resolution (``scale`` multiplies the
sizes, e.g. for a HiDPI window), so a supersampled picture still gets sharp text.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..fields.field import date_of
from .colormaps import colormap_lut
from .style.model import ColorMap, Style, WidthMap

Box = tuple[int, int, int, int]  # x0, y0, x1, y1 (pixels, y down, x1/y1 exclusive)


# -- numbers ------------------------------------------------------------------------------------
def nice_ticks(lo: float, hi: float, n: int = 5) -> list[float]:
    """Round numbers within [lo, hi], 1, 2, 2.5 or 5 times a power of ten apart, as close to
    ``n`` of them as those steps allow (at least two where the range holds two)."""
    a, b = min(lo, hi), max(lo, hi)
    if not (math.isfinite(a) and math.isfinite(b)) or b <= a:
        return [a]
    p = 10.0 ** math.floor(math.log10((b - a) / max(n - 1, 1)))
    best = None
    for step in (m * p * s for s in (0.1, 1.0, 10.0) for m in (1, 2, 2.5, 5)):
        k0, k1 = math.ceil(a / step - 1e-9), math.floor(b / step + 1e-9)
        count = k1 - k0 + 1
        score = (count < 2, abs(count - n), -step)
        if best is None or score < best[0]:
            best = (score, [k * step for k in range(k0, k1 + 1)])
    return best[1]


def fitting_ticks(lo: float, hi: float, width: float, length, gap: float):
    """(ticks, labels): as many round ticks (5 down to 2) as fit under a bar ``width`` pixels
    wide from ``lo`` to ``hi`` with each label (``length(text)`` pixels wide) centred on its
    tick and ``gap`` pixels clear of its neighbours."""
    def fits(ticks, names):
        at = [(v - lo) / (hi - lo) * width for v in ticks]
        half = [length(t) / 2 for t in names]
        return all(at[i + 1] - at[i] >= half[i] + half[i + 1] + gap for i in range(len(at) - 1))

    for n in (5, 4, 3, 2):
        ticks = nice_ticks(lo, hi, n)
        names = tick_labels(ticks)
        if fits(ticks, names):
            return ticks, names
    ends = [0, len(ticks) - 1] if len(ticks) > 1 else [0]  # the first and last, else one
    if not fits([ticks[i] for i in ends], [names[i] for i in ends]):
        ends = [0]
    return [ticks[i] for i in ends], [names[i] for i in ends]


def round_down(x: float) -> float:
    """The largest 1, 2 or 5 times a power of ten not above ``x`` > 0."""
    p = 10.0 ** math.floor(math.log10(x))
    return max(m * p for m in (1, 2, 5) if m * p <= x * (1 + 1e-9))


def tick_labels(ticks: list[float]) -> list[str]:
    """Labels with as many decimals as the tick step needs (no float noise)."""
    if len(ticks) < 2:
        return [f"{t:g}" for t in ticks]
    step = abs(ticks[1] - ticks[0])
    big = max(abs(t) for t in ticks)
    if big >= 1e6 or big < 1e-3:
        return [f"{t:.3g}" for t in ticks]
    d = max(0, -math.floor(math.log10(step) + 1e-9))
    while d < 12 and abs(round(step, d) - step) > 1e-9 * step:  # 0.25 needs two decimals
        d += 1
    return [f"{0.0 if abs(t) < step * 1e-6 else t:.{d}f}" for t in ticks]


def label(name: str, units: dict[str, str] | None) -> str:
    u = (units or {}).get(name)
    return f"{name} [{u}]" if u else name


# -- drawing helpers ----------------------------------------------------------------------------
def text_font(px: float):
    """Pillow's own scalable font at about ``px`` pixels (no system fonts: the same text
    everywhere); the viewer's overlays use it too."""
    return _font_at(max(6, round(px)))


@functools.cache
def _font_at(size: int):
    from PIL import ImageFont

    return ImageFont.load_default(size=size)


def _colours(style: Style) -> tuple[tuple, tuple]:
    """(panel fill, ink) RGBA 0..255 readable on the style's background."""
    bg = style.background or (1.0, 1.0, 1.0, 1.0)
    lum = 0.2126 * bg[0] + 0.7152 * bg[1] + 0.0722 * bg[2]
    fill = tuple(round(255 * c) for c in bg[:3]) + (220,)
    ink = (20, 20, 20, 255) if lum > 0.5 else (240, 240, 240, 255)
    return fill, ink


def _rgba255(c) -> tuple:
    return tuple(round(255 * float(v)) for v in c)


def _swatch_colour(style: Style, name: str) -> tuple:
    """A line style's innermost band colour (a colormap's middle)."""
    c = style.styles[name].bands[0].color
    if isinstance(c, ColorMap):
        lut = colormap_lut(c.cmap)
        return _rgba255(lut[len(lut) // 2])
    return _rgba255(c)


def _maps(style: Style):
    """(kind, map) for the colour and width maps of the drawn styles, each once."""
    seen, out = set(), []
    for n in style.used_styles():
        for b in style.styles[n].bands:
            for m in (b.color, b.pattern.color if b.pattern is not None else None, b.width):
                if isinstance(m, (ColorMap, WidthMap)):
                    key = (type(m).__name__, m.attribute, getattr(m, "cmap", None), m.range)
                    if key not in seen:
                        seen.add(key)
                        out.append(m)
    return out


def drawn_pixels(image: np.ndarray, style: Style) -> np.ndarray:
    """(H, W) bool: the pixels of a picture of ``style`` that differ from its background (what
    "auto" placement keeps the legend off)."""
    bg = np.array([round(255 * c) for c in (style.background or (0, 0, 0, 0))], int)
    k = 4 if style.background is None else 3  # on an opaque background the colour tells
    return np.abs(image[:, :, :k].astype(int) - bg[:k]).max(axis=2) > 16


def legend_key(style: Style) -> tuple:
    """What ``legend_image`` draws of ``style`` (ranges as numbers): equal keys, equal legends
    at one size, so a caller redraws its legend only when this changes."""
    tf = style.transfer
    swatches = () if tf is None else tuple(_swatch_colour(style, r.style) for r in tf.ranges
                                           if r.style is not None)
    return tuple(_maps(style)), tf, swatches, style.background, style.legend


# -- the legend ---------------------------------------------------------------------------------
def legend_image(style: Style, size: tuple[int, int], *, units: dict[str, str] | None = None,
                 scale: float = 1.0, placement: str | None = None,
                 coverage: np.ndarray | None = None,
                 text_px: float | None = None) -> tuple[np.ndarray, Box | None]:
    """The legend of ``style`` for a ``size`` = (width, height) picture.

    ``style``: ranges already numbers (``LineRenderer.resolve``).  ``units``: attribute ->
    units (``Lines.units``).  ``scale``: multiplies text and bar sizes.  ``text_px``: the text
    size in pixels instead of 1/24 of the picture's smaller side (a window's legend keeps the
    size of the window's other text).  ``placement``: one of
    PLACEMENTS (default: the style's ``[legend] placement``); "auto" puts the panel in the corner
    where ``coverage`` ((H, W) bool, the drawn pixels) has the fewest pixels under it (top-right
    without ``coverage``).  Returns (RGBA uint8 (H, W, 4), box (x0, y0, x1, y1)), or an empty
    image and None when the style maps nothing to show.
    """
    from PIL import Image, ImageDraw

    w, h = (int(v) for v in size)
    out = np.zeros((h, w, 4), np.uint8)
    tf = style.transfer
    maps = _maps(style)
    if not maps and tf is None:
        return out, None
    fs = (text_px or max(10.0, min(w, h) / 24)) * scale  # font size, pixels
    font, small = text_font(fs), text_font(0.85 * fs)
    fill, ink = _colours(style)
    pad, gap = round(0.5 * fs), round(0.45 * fs)
    bar_w, bar_h = round(min(max(9 * fs, 0.22 * w), 0.45 * w)), round(0.8 * fs)
    blocks = []  # (height, draw(d, x, y))

    def text_h(f, s="Ag"):
        box = f.getbbox(s)
        return box[3] - min(box[1], 0)

    th, sh = text_h(font), text_h(small)
    for m in maps:
        title = label(m.attribute, units) + ("" if isinstance(m, ColorMap) else " (width)")
        lo, hi = m.range
        ticks, names = fitting_ticks(lo, hi, bar_w, small.getlength, gap)

        def draw(d, x, y, m=m, title=title, lo=lo, hi=hi, ticks=ticks, names=names):
            d.text((x, y), title, font=font, fill=ink)
            y0 = y + th + gap // 2
            if isinstance(m, ColorMap):
                lut = colormap_lut(m.cmap)
                t = np.linspace(0.0, 1.0, bar_w)
                rgb = np.stack([np.interp(t, np.linspace(0, 1, len(lut)), lut[:, c])
                                for c in range(3)], 1)
                strip = np.repeat((np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8)[None],
                                  bar_h, 0)
                bar = Image.fromarray(np.dstack([strip, np.full(strip.shape[:2], 255, np.uint8)]),
                                      "RGBA")
                d._image.paste(bar, (x, y0))
                d.rectangle((x - 1, y0 - 1, x + bar_w, y0 + bar_h), outline=ink)
            else:  # a wedge from the thinnest to the widest line
                span = max(m.min, m.max, 1e-9)
                a, b = bar_h * m.min / span, bar_h * m.max / span
                mid = y0 + bar_h / 2
                d.polygon([(x, mid - a / 2), (x + bar_w, mid - b / 2), (x + bar_w, mid + b / 2),
                           (x, mid + a / 2)], fill=ink)
            for v, s in zip(ticks, names):
                tx = x + (v - lo) / (hi - lo) * (bar_w - 1)
                d.line((tx, y0 + bar_h, tx, y0 + bar_h + gap // 2), fill=ink)
                tw = d.textlength(s, font=small)
                d.text((min(max(tx - tw / 2, x - pad // 2), x + bar_w - tw + pad // 2),
                        y0 + bar_h + gap // 2), s, font=small, fill=ink)

        blocks.append((th + gap // 2 + bar_h + gap // 2 + sh, draw))
    if tf is not None:
        rows = [(r, f"{r.style}: {_bound(r.range[0])} to {_bound(r.range[1])}")
                for r in tf.ranges if r.style is not None]

        def draw_tf(d, x, y, rows=rows):
            d.text((x, y), label(tf.attribute, units) + " (line style)", font=font, fill=ink)
            y += th + gap // 2
            for r, s in rows:
                d.rectangle((x, y + sh * 0.2, x + 1.6 * fs, y + sh * 0.9),
                            fill=_swatch_colour(style, r.style), outline=ink)
                d.text((x + 2.1 * fs, y), s, font=small, fill=ink)
                y += sh + gap // 2

        blocks.append((th + gap // 2 + len(rows) * (sh + gap // 2), draw_tf))
    tw_max = max([bar_w] + [round(font.getlength(label(m.attribute, units) + " (width)"))
                            for m in maps] + ([round(font.getlength(
                                label(tf.attribute, units) + " (line style)"))] if tf else []))
    pw = min(tw_max + 2 * pad, w)
    ph = min(sum(b[0] for b in blocks) + gap * (len(blocks) - 1) + 2 * pad, h)
    box = _place(placement or style.legend.placement, (w, h), (pw, ph), coverage,
                 margin=round(0.02 * min(w, h)))
    img = Image.fromarray(out, "RGBA")
    d = ImageDraw.Draw(img)
    d.rounded_rectangle((box[0], box[1], box[2] - 1, box[3] - 1), radius=round(0.3 * fs),
                        fill=fill)  # Pillow's corners are inclusive, the box's end exclusive
    y = box[1] + pad
    for bh, draw in blocks:
        draw(d, box[0] + pad, y)
        y += bh + gap
    return np.asarray(img).copy(), box


def _bound(v: float) -> str:
    return "-inf" if v == -math.inf else "inf" if v == math.inf else f"{v:.3g}"


def _place(placement: str, size, panel, coverage, margin: int) -> Box:
    w, h = size
    pw, ph = panel
    corners = {"top-left": (margin, margin), "top-right": (w - pw - margin, margin),
               "bottom-left": (margin, h - ph - margin),
               "bottom-right": (w - pw - margin, h - ph - margin)}
    if placement in ("auto", "outside"):  # (outside: the caller widened the canvas)
        if coverage is None:
            placement = "top-right"
        else:
            def covered(xy):
                x, y = max(xy[0], 0), max(xy[1], 0)
                return int(coverage[y:y + ph, x:x + pw].sum())
            # ties: the order of the corners in PLACEMENTS
            placement = min(corners, key=lambda k: covered(corners[k]))
    x, y = corners[placement]
    x, y = max(x, 0), max(y, 0)
    return x, y, min(x + pw, w), min(y + ph, h)


# -- annotations --------------------------------------------------------------------------------
def time_label(t: float, origin: str | None = None) -> str:
    """``t = 2000 s``, or where times are dates (seconds since ``origin``, an ISO date) the date:
    ``t = 2024-03-01 12:00:30`` (milliseconds where there are any)."""
    return f"t = {date_of(t, origin)}" if origin else f"t = {t:g} s"


def annotation_image(size: tuple[int, int], style: Style, *, title: str = "",
                     time: float | None = None, time_origin: str | None = None, text: str = "",
                     world_per_pixel: float | None = None, length_units: str | None = None,
                     scale: float = 1.0, avoid: Box | None = None,
                     coverage: np.ndarray | None = None,
                     text_px: float | None = None) -> tuple[np.ndarray, Box | None]:
    """Title, the time (``time_label``) and free text, and with ``world_per_pixel`` a scale bar
    of a round length in world units labelled with ``length_units``.  The title goes top or
    bottom centre, the rest (stacked, the scale bar lowest) in a corner: where they cover the
    fewest pixels of ``coverage`` ((H, W) bool, the drawn pixels) and not ``avoid`` (e.g. the
    legend's box); without ``coverage``, top centre and the bottom corner away from ``avoid``.
    ``text_px``: the text size instead of 1/24 of the smaller side.  Returns (RGBA uint8
    (H, W, 4), the box around all of them) or an empty image and None when there is nothing."""
    from PIL import Image, ImageDraw

    w, h = (int(v) for v in size)
    img = Image.new("RGBA", (w, h), (0, 0, 0, 0))
    d = ImageDraw.Draw(img)
    fs = (text_px or max(10.0, min(w, h) / 24)) * scale
    font, big = text_font(fs), text_font(1.3 * fs)
    fill, ink = _colours(style)
    margin, pad = round(0.02 * min(w, h)), round(0.3 * fs)
    taken = [avoid] if avoid is not None else []
    boxes = []

    def cost(box) -> float:
        """Drawn pixels under ``box``, anything taken under it counting as all covered."""
        x0, y0, x1, y1 = (round(v) for v in box)
        hit = sum(1 for t in taken if x0 < t[2] and t[0] < x1 and y0 < t[3] and t[1] < y1)
        under = coverage[max(y0, 0):max(y1, 0), max(x0, 0):max(x1, 0)].sum() if coverage is \
            not None else 0
        return float(under) + hit * (x1 - x0) * (y1 - y0) + 1.0

    if title:
        tb = d.textbbox((0, 0), title, font=big)
        tw = tb[2] - tb[0]
        spots = [((w - tw) / 2, margin - tb[1] + pad), ((w - tw) / 2, h - margin - pad - tb[3])]
        x, y = spots[0] if coverage is None else min(spots, key=lambda xy: cost(
            (xy[0] - pad, xy[1] + tb[1] - pad, xy[0] + tw + pad, xy[1] + tb[3] + pad)))
        b = (x - pad, y + tb[1] - pad, x + tw + pad, y + tb[3] + pad)
        d.rounded_rectangle(b, radius=pad, fill=fill)
        d.text((x, y), title, font=big, fill=ink)
        boxes.append(b)
        taken.append(b)
    # the stack: text lines (top down), then the scale bar; sizes first, then a corner
    lines = [s for s in (time_label(time, time_origin) if time is not None else "", text) if s]
    rows = []  # (width, height, draw(x, y): y its top)
    for s in lines:
        tb = d.textbbox((0, 0), s, font=font)

        def put(x, y, s=s, tb=tb):
            b = (x - pad, y - pad, x + tb[2] - tb[0] + pad, y + tb[3] - tb[1] + pad)
            d.rounded_rectangle(b, radius=pad, fill=fill)
            d.text((x - tb[0], y - tb[1]), s, font=font, fill=ink)
        rows.append((tb[2] - tb[0], tb[3] - tb[1], put))
    if world_per_pixel is not None and world_per_pixel > 0 and math.isfinite(world_per_pixel):
        length = round_down(0.2 * w * world_per_pixel)
        px = length / world_per_pixel
        s = f"{length:g} {length_units}" if length_units else f"{length:g}"
        bh = max(3, round(0.25 * fs))
        tb = d.textbbox((0, 0), s, font=font)

        def bar(x, y, s=s, tb=tb, px=px, bh=bh):
            d.rounded_rectangle((x - pad, y - pad, x + px + pad, y + tb[3] - tb[1] + 2 * pad + bh),
                                radius=pad, fill=fill)
            d.text((x + px / 2 - d.textlength(s, font=font) / 2, y - tb[1]), s, font=font,
                   fill=ink)
            yb = y + tb[3] - tb[1] + pad
            d.rectangle((x, yb, x + px, yb + bh), fill=ink)
        rows.append((px, tb[3] - tb[1] + pad + bh, bar))
    if rows:
        bw = max(r[0] for r in rows) + 2 * pad
        bh_all = sum(r[1] + 2 * pad for r in rows) + pad * (len(rows) - 1)
        xs = {"left": margin, "right": w - margin - bw}
        ys = {"bottom": h - margin - bh_all, "top": margin}
        away, near = ("left", "right") if avoid is None or avoid[0] > w / 2 else ("right", "left")
        # in order of preference on ties: the bottom corner away from the legend first
        corners = {f"{v}-{u}": (xs[u], ys[v]) for v in ("bottom", "top") for u in (away, near)}
        key = next(iter(corners))
        if coverage is not None:
            key = min(corners, key=lambda k: cost((*corners[k], corners[k][0] + bw,
                                                   corners[k][1] + bh_all)))
        x0, y = corners[key]
        right = key.endswith("right")
        for rw, rh, draw in rows:
            draw(x0 + pad + (bw - 2 * pad - rw if right else 0), y + pad)
            y += rh + 3 * pad
        boxes.append((x0, corners[key][1], x0 + bw, corners[key][1] + bh_all))
    if not boxes:
        return np.asarray(img).copy(), None
    box = (max(0, min(b[0] for b in boxes)), max(0, min(b[1] for b in boxes)),
           min(w, max(b[2] for b in boxes)), min(h, max(b[3] for b in boxes)))
    return np.asarray(img).copy(), tuple(int(v) for v in box)


def composite(image: np.ndarray, overlay: np.ndarray) -> np.ndarray:
    """``overlay`` (RGBA uint8) over ``image`` (RGBA uint8, same size), Porter-Duff "over"."""
    a = overlay[..., 3:4].astype(np.float32) / 255.0
    if not a.any():
        return image
    base = image.astype(np.float32)
    ab = base[..., 3:4] / 255.0
    out_a = a + ab * (1.0 - a)
    rgb = (overlay[..., :3] * a + base[..., :3] * ab * (1.0 - a)) / np.maximum(out_a, 1e-6)
    return np.clip(np.rint(np.dstack([rgb, out_a * 255.0])), 0, 255).astype(np.uint8)
