"""Render the gallery: one style per figure of the paper's Results section (examples/gallery/),
each on streamlines of the heated-room demo data, to docs/gallery/<style>.png.

    .venv/bin/python scripts/make_gallery.py [--size 1200x675] [--only 04_arrows]

Then the seeding pair (``--only seeding``): evenly spaced lines of the heated room (dsep =
diagonal / 20) beside as many lines from uniform random seeds, in style 02, traced alike.

The lines: the last snapshot (t = 2000 s, closest to steady), seeds on a 6 x 2 x 6 lattice in
the middle of the room (2..8 m across, 0.5..2.5 m high, around the heater's plume), traced
12 m both ways from each seed, vertices every 4 cm, with the attributes the gallery styles read.  Look at every PNG after a change.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
STYLES = ROOT / "examples" / "gallery"
OUT = ROOT / "docs" / "gallery"


def gallery_lines(n=(6, 2, 6), max_length=12.0, spacing=0.04):
    """Streamlines of the heated room from an n[0] x n[1] x n[2] seed lattice (y up)."""
    from flowkit import trace
    from flowkit.datasets import hotroom
    from flowkit.integrate import seeds

    attributes = sorted({a for p in style_paths() for a in _load(p).attributes()})
    return trace(hotroom(), seeds.box((2.0, 0.5, 2.0), (8.0, 2.5, 8.0), n), direction="both",
                 max_length=max_length, spacing=spacing, stagnation=1e-4,
                 attributes=tuple(attributes))


SEEDING_STYLE = "02_speed_bupu_white_halo"


def seeding_lines(fraction=20.0, max_length=12.0, seed=0):
    """The heated room's evenly spaced lines (dsep = diagonal / ``fraction``) and as many
    lines from uniform random seeds, traced alike (both ways, ``max_length`` each way)."""
    import numpy as np

    from flowkit import trace
    from flowkit.datasets import hotroom
    from flowkit.integrate import seeds
    from flowkit.seeding.even import evenly_spaced

    field = hotroom()
    style = _load(STYLES / f"{SEEDING_STYLE}.toml")
    kw = {"direction": "both", "max_length": max_length, "stagnation": 1e-4,
          "attributes": tuple(sorted(style.attributes()))}
    diag = float(np.linalg.norm(np.diff(field.grid.bounds, axis=1)))
    even = evenly_spaced(field, diag / fraction, seed=seed, **kw)
    rand = trace(field, seeds.random_in(field, len(even), seed=seed),
                 spacing=even.attrs["dtest"] / 2, **kw)
    return even, rand


def render_seeding(size, out=OUT, **kw):
    """docs/gallery/seeding_random.png and seeding_even.png: the same style on both."""
    from flowkit.render import LineRenderer, save_png

    style = _load(STYLES / f"{SEEDING_STYLE}.toml")
    even, rand = seeding_lines(**kw)
    paths = []
    for name, lines in (("seeding_random", rand), ("seeding_even", even)):
        with LineRenderer(lines) as r:
            paths.append(save_png(r.render(style, size, room_camera(), overlays=True),
                                  out / f"{name}.png"))
    return paths, even, rand


def style_paths() -> list[Path]:
    return sorted(STYLES.glob("*.toml"))


def _load(path):
    from flowkit.render import load_style

    return load_style(path)


def room_camera():
    """The heated room's view (y up, seen from the front, a little above): the styles carry no
    camera, so that they draw any dataset from its automatic view."""
    from flowkit.render import Camera

    return Camera(azimuth=-70, elevation=18, up=(0, 1, 0))


def render_gallery(lines, size, only=None, out=OUT, renderer=None, camera="room"):
    """Render every gallery style (or those whose name contains ``only``) with ``camera``
    ("room": ``room_camera``; None: the automatic view); yields (style path, image)."""
    from flowkit.render import LineRenderer

    camera = room_camera() if camera == "room" else camera

    r = renderer or LineRenderer(lines)
    try:
        for p in style_paths():
            if only and only not in p.stem:
                continue
            yield p, r.render(_load(p), size, camera, overlays=True)
    finally:
        if renderer is None:
            r.release()


def main(argv=None) -> int:
    from flowkit.render import save_png

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="1200x675")
    ap.add_argument("--only", help="render only styles whose file name contains this")
    a = ap.parse_args(argv)
    size = tuple(int(v) for v in a.size.split("x"))
    lines = gallery_lines()
    print(f"{len(lines)} lines, {lines.n_points:,} vertices")
    OUT.mkdir(parents=True, exist_ok=True)
    for p, img in render_gallery(lines, size, a.only):
        path = save_png(img, OUT / f"{p.stem}.png")
        print(f"wrote {path.relative_to(ROOT)}")
    if not a.only or "seeding" in a.only:
        paths, even, rand = render_seeding(size)
        print(f"seeding: {len(even)} evenly spaced lines ({even.n_points:,} vertices), "
              f"{len(rand)} random ones ({rand.n_points:,} vertices)")
        for path in paths:
            print(f"wrote {path.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
