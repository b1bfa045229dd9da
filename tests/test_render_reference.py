"""Reference images compared with a tolerance (llvmpipe).

Regenerate after an intended visual change, then look at the PNGs before committing:
    FLOWKIT_REGEN_REFERENCE=1 .venv/bin/python -m pytest tests/test_render_reference.py
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from render_scenes import helices, style

from flowkit.render import Band, Camera, ColorMap, WidthMap, render_lines, save_png

REF = Path(__file__).resolve().parent / "reference_images"
REGEN = os.environ.get("FLOWKIT_REGEN_REFERENCE") == "1"

SCENES = {
    "helix_halo_perspective": (
        style(Band((1, 1, 1, 1), 2.0), Band((0, 0, 0, 1), 1.5, depth_offset=0.15),
              background=(0.85, 0.85, 0.85, 1)), Camera(azimuth=-60, elevation=25)),
    "helix_colormap_width_ortho": (
        style(Band(ColorMap("viridis", "speed", (0, 1)), WidthMap("speed", (0, 1), 0.5, 3.0)),
              Band((1, 1, 1, 1), 1.0, depth_offset=0.15), background=(0.1, 0.1, 0.1, 1)),
        Camera(azimuth=20, elevation=40, projection="orthographic")),
}


@pytest.mark.parametrize("name", sorted(SCENES))
def test_reference_image(name):
    s, cam = SCENES[name]
    img = render_lines(helices(), s, (160, 120), cam)
    path = REF / f"{name}.png"
    if REGEN:
        save_png(img, path)
    ref = np.asarray(Image.open(path).convert("RGBA"))
    diff = np.abs(img.astype(int) - ref.astype(int)).max(axis=2)
    # llvmpipe versions may differ by rounding at edges: few pixels may differ much
    assert diff.mean() < 2.0, f"{name}: mean difference {diff.mean():.2f}"
    assert np.mean(diff > 40) < 0.01, f"{name}: {np.mean(diff > 40):.2%} pixels differ by > 40"
