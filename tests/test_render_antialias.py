"""Antialiasing policy: a style's antialias = "msaa" gets 4x MSAA on a GPU and analytic edge
smoothing on a software rasterizer (llvmpipe here) unless the renderer is told otherwise; the MSAA
path still reproduces its reference images."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from render_scenes import FACE_ON, helices, straight, style
from test_render_reference import SCENES

from flowkit.render import Band, LineRenderer, default_context
from flowkit.render.context import is_software

REF = Path(__file__).resolve().parent / "reference_images"
RED, WHITE = (1, 0, 0, 1), (1, 1, 1, 1)


def test_llvmpipe_is_software_and_gets_analytic_edges_by_default():
    ctx = default_context()
    assert "llvmpipe" in ctx.info["GL_RENDERER"] and is_software(ctx)
    s = style(Band(RED, 2.0))
    assert s.antialias == "msaa"
    lines = straight((-1, 0, 0), (1, 0, 0))
    with LineRenderer(lines) as auto, LineRenderer(lines, msaa=True) as forced:
        assert auto.tolerance == 0.25 and not auto.msaa  # software defaults (GPU: 0, MSAA)
        with ctx:  # prepare() compiles: it needs the context current
            assert auto.samples_for(s) == 1 and auto.prepare(s)[0].smooth_edge
            assert forced.samples_for(s) == 4 and not forced.prepare(s)[0].smooth_edge
        for r in (auto, forced):  # both antialias a half-covered edge row
            # the line centre sits on a pixel boundary; 2.5 px half-width: edge rows half covered
            img = r.render(style(Band(RED, 2.5), background=WHITE), (200, 100), FACE_ON)
            col = img[:, 100, :3].astype(int)
            assert tuple(col[50]) == (255, 0, 0) and tuple(col[48]) == (255, 0, 0)
            assert tuple(col[44]) == (255, 255, 255) and tuple(col[55]) == (255, 255, 255)
            for row in (47, 52):  # offsets 2.5 and -2.5: half red, half white
                assert col[row, 0] == 255 and 100 < col[row, 1] < 155, (row, col[row])


@pytest.mark.parametrize("name", sorted(SCENES))
def test_msaa_path_matches_its_reference_images(name):
    s, cam = SCENES[name]
    with LineRenderer(helices(), msaa=True) as r:
        img = r.render(s, (160, 120), cam)
    ref = np.asarray(Image.open(REF / f"msaa_{name}.png").convert("RGBA"))
    diff = np.abs(img.astype(int) - ref.astype(int)).max(axis=2)
    assert diff.mean() < 2.0, f"{name}: mean difference {diff.mean():.2f}"
    assert np.mean(diff > 40) < 0.01
