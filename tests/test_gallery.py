"""Every gallery style (one per figure of the paper's Results section) loads, renders the
heated-room streamlines non-blank, and differs from every other gallery style."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from flowkit.render import LineRenderer, load_style

ROOT = Path(__file__).resolve().parent.parent
_spec = importlib.util.spec_from_file_location("make_gallery", ROOT / "scripts" / "make_gallery.py")
make_gallery = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(make_gallery)

SIZE = (240, 135)


@pytest.fixture(scope="module")
def images():
    lines = make_gallery.gallery_lines(n=(3, 2, 3), max_length=8.0, spacing=0.08)
    with LineRenderer(lines) as r:
        return {p.stem: img for p, img in make_gallery.render_gallery(lines, SIZE, renderer=r)}


def test_gallery_has_one_style_per_results_figure():
    names = [p.stem for p in make_gallery.style_paths()]
    assert [n[:2] for n in names] == [f"{k:02d}" for k in range(1, 9)]
    kinds = [load_style(p) for p in make_gallery.style_paths()]
    bands = [[b for n in s.used_styles() for b in s.styles[n].bands] for s in kinds]
    assert [b.shape.name for b in bands[3] if b.shape] == ["arrow"]  # (4) arrows
    assert kinds[3].line_style.bands[0].shape.attribute == "time"  # size shows speed
    assert [b.shape.name for b in bands[5] if b.shape] == ["tadpole"]  # (6)
    assert kinds[5].line_style.bands[0].shape.attribute == "arc_length"  # fixed size
    assert bands[6][0].pattern.attribute == "time" and bands[6][0].width.attribute == "speed"
    assert kinds[7].transfer.attribute == "distance_to_seed"  # (8)
    assert [b.shape.name for b in kinds[7].styles["context"].bands] == ["dash"]
    for name in names:  # committed pictures for the gallery page
        assert (ROOT / "docs" / "gallery" / f"{name}.png").is_file(), name
        assert f"gallery/{name}.png" in (ROOT / "docs" / "gallery.md").read_text()


def test_every_gallery_style_renders_non_blank_and_distinct(images):
    assert len(images) == 8
    for name, img in images.items():
        bg = img[0, 0, :3].astype(int)
        drawn = np.any(np.abs(img[:, :, :3].astype(int) - bg) > 30, axis=2)
        assert drawn.mean() > 0.03, f"{name}: only {drawn.mean():.1%} of the pixels drawn"
    names = sorted(images)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            diff = np.abs(images[a].astype(int) - images[b].astype(int)).max(axis=2)
            assert np.mean(diff > 30) > 0.02, f"{a} and {b} look the same"


def test_seeding_pair_evenly_spaced_beside_random():
    """The gallery's seeding pair: the same style on evenly spaced and on random lines (as
    many of each), both committed; evenly spaced lines use far fewer vertices for the same
    number of lines (they stop where they would crowd another) and draw a different picture."""
    text = (ROOT / "docs" / "gallery.md").read_text()
    for name in ("seeding_random", "seeding_even"):
        assert (ROOT / "docs" / "gallery" / f"{name}.png").is_file()
        assert f"gallery/{name}.png" in text
    even, rand = make_gallery.seeding_lines(fraction=10.0, max_length=6.0)
    assert len(even) == len(rand) > 10
    assert even.n_points < 0.7 * rand.n_points
    style = load_style(make_gallery.STYLES / f"{make_gallery.SEEDING_STYLE}.toml")
    imgs = []
    for lines in (even, rand):
        with LineRenderer(lines) as r:
            imgs.append(r.render(style, SIZE, make_gallery.room_camera()))
    for img in imgs:
        bg = img[0, 0, :3].astype(int)
        assert np.any(np.abs(img[:, :, :3].astype(int) - bg) > 30, axis=2).mean() > 0.03
    assert np.mean(np.abs(imgs[0].astype(int) - imgs[1].astype(int)).max(axis=2) > 30) > 0.02
