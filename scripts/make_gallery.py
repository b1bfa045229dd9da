"""Render the gallery: one style per figure of the paper's Results section (examples/gallery/),
each on streamlines of the heated-room demo data, to docs/gallery/<style>.png.

    .venv/bin/python scripts/make_gallery.py [--size 1200x675] [--only 04_arrows]

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


def style_paths() -> list[Path]:
    return sorted(STYLES.glob("*.toml"))


def _load(path):
    from flowkit.render import load_style

    return load_style(path)


def render_gallery(lines, size, only=None, out=OUT, renderer=None):
    """Render every gallery style (or those whose name contains ``only``); yields
    (style path, image)."""
    from flowkit.render import LineRenderer

    r = renderer or LineRenderer(lines)
    try:
        for p in style_paths():
            if only and only not in p.stem:
                continue
            yield p, r.render(_load(p), size, overlays=True)
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
    return 0


if __name__ == "__main__":
    sys.exit(main())
