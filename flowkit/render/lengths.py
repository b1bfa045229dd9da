"""Style lengths relative to the scene, so that one style file draws alike on any dataset.

A length a style sets (band widths, depth offsets, shape and pattern lengths, a transfer
function's bounds on a length attribute) is a number in the style's own units, or a string:

- ``"2.5px"``: screen pixels (of the output image, at the depth of the point looked at);
- ``"1/200d"`` or ``"0.005d"``: a fraction of the diagonal of the lines' bounds, as seeding's
  ``even:1/30d``;
- ``"0.1z"``: a fraction of the scene's depth range (the bounds' extent along the view), the
  natural unit of a depth-dependent halo's offset (paper section 3.1), which only has to exceed
  the depth differences the halo should show;
- ``"0.05 m"`` (also cm, mm, km): world units with their unit stated, converted to the lines'
  ``length_units`` when they have them.

On an attribute measured in time (``time``), a length is the time the lines need to travel it at
their median speed.  ``resolve_lengths`` turns every string into a number before drawing.  (The style model
checks the strings with length_forms.py, below it; this module builds on the model.)
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from .length_forms import METRES, parse
from .style.check import StyleError
from .style.model import Transfer, WidthMap

LENGTH_ATTRIBUTES = ("arc_length", "distance_to_seed")
TIME_ATTRIBUTES = ("time",)


@dataclass(frozen=True)
class SceneScale:
    """What relative lengths are relative to, for one picture."""

    diagonal: float          # of the lines' bounds, world units
    depth: float             # the bounds' extent along the view direction, world units
    per_pixel: float         # world size of an output pixel at the depth looked at
    length_units: str | None = None  # the lines' (e.g. "m")
    speed: float | None = None       # the lines' median speed (for lengths on time)

    def world(self, v: float | str, where: str) -> float:
        """The length ``v`` in world units (a number: already world units)."""
        if not isinstance(v, str):
            return float(v)
        value, kind = parse(v)
        if kind == "px":
            return value * self.per_pixel
        if kind == "d":
            return value * self.diagonal
        if kind == "z":
            return value * self.depth
        have = self.length_units
        if have is None or have == kind:
            return value
        if have not in METRES:
            raise StyleError(f"{where} = {v!r}: the lines' lengths are in {have!r}, which cannot "
                             f"be converted from {kind!r}; give it relative ('1/200d', '2px')")
        return value * METRES[kind] / METRES[have]


def resolve_lengths(style, scale: SceneScale):
    """``style`` with every relative length (a string) replaced by its number: widths in the
    style's units, depth offsets in world units, shape and pattern lengths and transfer bounds
    in their attribute's units."""
    if not _has_strings(style):
        return style
    pixels = style.units == "pixels"

    def width(v, where):
        if not isinstance(v, str):
            return v
        w = scale.world(v, where)
        return w / scale.per_pixel if pixels else w

    def along(v, attribute, where):
        if not isinstance(v, str):
            return v
        if attribute in TIME_ATTRIBUTES:
            if not scale.speed:
                raise StyleError(f"{where} = {v!r} on '{attribute}': the lines have no speed to "
                                 "turn a length into a time; give seconds")
            return scale.world(v, where) / scale.speed
        if attribute not in LENGTH_ATTRIBUTES:
            raise StyleError(f"{where} = {v!r}: '{attribute}' is not a length or a time; give "
                             "a number in its units")
        return scale.world(v, where)

    def band(b, where: str):
        w = b.width
        if isinstance(w, WidthMap):
            w = dataclasses.replace(w, min=width(w.min, f"{where} width.min"),
                                    max=width(w.max, f"{where} width.max"))
        else:
            w = width(w, f"{where} width")
        sh, pt = b.shape, b.pattern
        if sh is not None:
            sh = dataclasses.replace(sh, length=along(sh.length, sh.attribute,
                                                      f"{where} shape.length"))
        if pt is not None:
            pt = dataclasses.replace(pt, length=along(pt.length, pt.attribute,
                                                      f"{where} pattern.length"))
        return dataclasses.replace(b, width=w, depth_offset=scale.world(
            b.depth_offset, f"{where} depth_offset"), shape=sh, pattern=pt)

    styles = {n: dataclasses.replace(ls, bands=tuple(band(b, f"style '{n}' band {i + 1}")
                                                     for i, b in enumerate(ls.bands)))
              for n, ls in style.styles.items()}
    tf = style.transfer
    if tf is not None:
        ranges = tuple(dataclasses.replace(r, range=tuple(
            along(v, tf.attribute, "[transfer] range") for v in r.range)) for r in tf.ranges)
        tf = Transfer(tf.attribute, ranges, tf.blend)
    return dataclasses.replace(style, styles=styles, transfer=tf)


def _has_strings(style) -> bool:
    for ls in style.styles.values():
        for b in ls.bands:
            w = b.width
            vals = [w.min, w.max] if isinstance(w, WidthMap) else [w]
            vals += [b.depth_offset, getattr(b.shape, "length", 0), getattr(b.pattern, "length", 0)]
            if any(isinstance(v, str) for v in vals):
                return True
    return style.transfer is not None and any(isinstance(v, str) for r in style.transfer.ranges
                                              for v in r.range)
