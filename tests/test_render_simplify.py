"""Per-frame level of detail (flowkit.render.simplify): Douglas-Peucker importance, the kept
vertices stay within the pixel tolerance, attributes keep the vertices their mapping needs, and
pictures drawn with and without it agree."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest
from render_scenes import FACE_ON, helices, style

from flowkit.lines import Lines
from flowkit.render import Band, Camera, ColorMap, LineRenderer, WidthMap, render_lines
from flowkit.render.simplify import (
    MAX_SPAN,
    arc_parameter,
    attribute_importance,
    attribute_tolerances,
    displacement_importance,
    geometry_importance,
    hermite,
    lod_importance,
    mapped_importance,
    runs,
    select,
    slopes,
)

BLACK, WHITE = (0, 0, 0, 1), (1, 1, 1, 1)


def _kept(ids):
    """Kept point ids per run from the doubled id buffer."""
    k = ids[::2]
    out, cur = [], []
    for v in k[1:]:
        if v < 0:
            if cur:
                out.append(cur)
            cur = []
        else:
            cur.append(int(v))
    return out


def test_runs_split_at_non_finite_points_and_lines():
    pts = np.zeros((9, 3))
    pts[:, 0] = np.arange(9)
    pts[3] = np.nan
    lines = Lines(pts, [0, 6, 7, 9])  # line 0 = 0,1,2 | nan | 4,5 ; line 1 = 6 (alone); line 2
    starts, stops = runs(lines)
    assert starts.tolist() == [0, 4, 7] and stops.tolist() == [3, 6, 9]


def test_importance_is_the_douglas_peucker_distance_capped_by_the_parent():
    # a tent: the apex is 2 from the base chord, one flank point off its chord, one on it
    x = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    y = np.array([0.0, 0.6, 2.0, 1.0, 0.0])
    pts = np.c_[x, y, np.zeros(5)]
    s, e = np.array([0]), np.array([5])
    imp = geometry_importance(pts, s, e)
    assert np.isinf(imp[0]) and np.isinf(imp[4])
    assert imp[2] == pytest.approx(2.0)  # apex: distance to the base chord
    # left flank point: distance to chord (0,0)-(2,2) is |0.6 - 1| / sqrt(2)
    assert imp[1] == pytest.approx(abs(y[1] - 1.0) / np.sqrt(2), rel=1e-6)
    assert imp[3] == pytest.approx(0.0, abs=1e-7)  # on the chord (2,2)-(4,0)
    # a child farther from its chord (2.76) than its parent (2) is capped at the parent's value:
    # a tolerance that drops the parent drops the child too
    pts2 = np.array([[0, 0, 0], [2, -1.9, 0], [2, 2, 0], [3, 1, 0], [4, 0, 0.0]])
    imp2 = geometry_importance(pts2, s, e)
    assert imp2[2] == pytest.approx(2.0) and imp2[1] == pytest.approx(2.0)


def test_kept_vertices_stay_within_the_pixel_tolerance_of_every_dropped_one():
    # a dense circle (radius 100 world units, orthographic 1 unit per pixel): DP must keep a
    # polygon whose chords are within tol pixels of every original vertex; n > MAX_SPAN, so the
    # first split is the forced middle one
    assert MAX_SPAN < 5000
    n = 5000
    t = np.linspace(0, 2 * np.pi, n)
    pts = np.c_[100 * np.cos(t), 100 * np.sin(t), np.zeros(n)]
    s, e = np.array([0]), np.array([n])
    imp = geometry_importance(pts, s, e)
    view = np.eye(4)
    for tol in (0.1, 0.5, 2.0):
        ids, idx = select(pts, imp, view, (0.0, 1.0), tol, np.zeros(0, bool), s, e)
        kept = np.array(_kept(ids)[0])
        assert kept[0] == 0 and kept[-1] == n - 1 and (n - 1) // 2 in kept
        # chord sagitta for a 100-px radius: a polygon of m sides deviates 100 (1 - cos(pi/m))
        assert len(kept) < n / 10
        for a, b in itertools.pairwise(kept):
            d = pts[b] - pts[a]
            m = pts[a + 1:b] - pts[a]
            dist = np.abs(m[:, 0] * d[1] - m[:, 1] * d[0]) / np.hypot(*d[:2])
            assert dist.size == 0 or dist.max() <= tol
        # the strip indices are the doubled kept positions and one restart
        assert idx.size == 2 * len(kept) + 1 and idx[-1] == 0xFFFFFFFF
    ids0, _ = select(pts, imp, view, (0.0, 1.0), 0.0, np.zeros(0, bool), s, e)
    assert _kept(ids0)[0] == list(range(n))  # tolerance 0: every vertex


def test_perspective_keeps_more_vertices_near_the_eye():
    # two identical dense wavy lines, one near the eye and one 10x farther
    n = 2000
    t = np.linspace(0, 1, n)
    wave = np.c_[t - 0.5, 0.01 * np.sin(40 * t), np.zeros(n)]
    near, far = wave + [0, 0, -1.0], wave + [0, 0, -10.0]
    pts = np.r_[near, far]
    s, e = np.array([0, n]), np.array([n, 2 * n])
    imp = geometry_importance(pts, s, e)
    ids, _ = select(pts, imp, np.eye(4), (1e-3, 0.0), 0.5, np.zeros(0, bool), s, e)
    k_near, k_far = map(len, _kept(ids))
    assert k_near > k_far * 2.5  # the far copy is 10x smaller on screen


def test_attribute_keeps_the_vertices_its_colormap_needs():
    n = 1000
    x = np.linspace(0, 1, n)
    pts = np.c_[x, np.zeros(n), np.zeros(n)]  # straight: geometry keeps only the ends
    wave = np.sin(6 * np.pi * x)
    lines = Lines(pts, [0, n], {"lin": x.copy(), "sq": x**2, "wave": wave})
    s, e = runs(lines)
    arc = arc_parameter(pts, s, e)
    assert arc[-1] == pytest.approx(1.0)
    for name in ("lin", "sq"):  # what a cubic through the ends draws exactly needs nothing
        v = lines.point_data[name]
        imp = attribute_importance(v, slopes(v, arc, s, e), arc, s, e)
        assert np.isinf(imp[[0, -1]]).all() and imp[1:-1].max() < 1e-12, name
    m = slopes(wave, arc, s, e)
    imp = attribute_importance(wave, m, arc, s, e)
    st = style(Band(ColorMap("viridis", "wave", (-1.0, 1.0)), 2.0))
    tol = attribute_tolerances(st, 0.25, {})
    assert tol == {"wave": pytest.approx(2 / 512)}
    keep = imp > 0.5 * tol["wave"]
    ids, _ = select(pts, geometry_importance(pts, s, e), np.eye(4), (0.0, 1.0), 0.25, keep, s, e)
    kept = np.array(_kept(ids)[0])
    # the interpolant the fragments get between the kept vertices is within the tolerance
    err = max(np.abs(hermite(wave, m, arc, i, j, arc[i:j + 1]) - wave[i:j + 1]).max()
              for i, j in itertools.pairwise(kept))
    assert err <= tol["wave"] and 8 < len(kept) < n / 10
    # linear interpolation through them would miss by far more
    assert np.abs(np.interp(x, x[kept], wave[kept]) - wave).max() > 4 * tol["wave"]


def _chord_errors(pts, arc, i, j):
    """Distances of the points between i and j from the chord i-j."""
    d = pts[j] - pts[i]
    t = np.clip((pts[i + 1:j] - pts[i]) @ d / (d @ d), 0.0, 1.0)
    return np.linalg.norm(pts[i + 1:j] - pts[i] - t[:, None] * d, axis=1)


def test_one_hierarchy_bounds_every_criterion_with_fewer_points_than_a_union():
    # a wavy 3-D curve with an attribute that places shapes (time-like) and one mapped to a
    # colormap (speed-like): the points one DP keeps at T bound the geometric deviation and the
    # placed attribute's displacement by T, and the mapped one's value error by its tolerance or
    # its displacement by T, on every chord -- and serve all three with fewer points than the
    # union of one hierarchy per criterion (which needs half the tolerance for the same bound)
    n = 3000
    x = np.linspace(0, 6, n)
    pts = np.c_[x, 0.3 * np.sin(2 * x), 0.2 * np.cos(3 * x)]
    s, e = np.array([0]), np.array([n])
    arc = arc_parameter(pts, s, e)
    speed = 1.2 + np.sin(1.7 * x) * np.cos(0.4 * x)
    time = np.cumsum(np.r_[0.0, np.diff(arc) / speed[1:]])
    mt, ms = slopes(time, arc, s, e), slopes(speed, arc, s, e)
    vtol, T = 1e-3, 2e-3
    imp = lod_importance(pts, arc, s, e, [(time, mt)], [(speed, ms, vtol)])
    kept = np.flatnonzero(imp > T)
    for i, j in itertools.pairwise(kept):
        if j - i < 2:
            continue
        assert _chord_errors(pts, arc, i, j).max() <= T
        at = arc[i + 1:j]
        terr = np.abs(hermite(time, mt, arc, i, j, at) - time[i + 1:j])
        assert (terr / np.abs(mt[i + 1:j])).max() <= T
        serr = np.abs(hermite(speed, ms, arc, i, j, at) - speed[i + 1:j])
        assert np.all((serr <= vtol) | (serr / np.maximum(np.abs(ms[i + 1:j]), 1e-300) <= T))
    union = ((geometry_importance(pts, s, e) > T / 2)
             | (displacement_importance(time, mt, arc, s, e) > T / 2)
             | (mapped_importance(speed, ms, arc, s, e, vtol) > T / 2))
    geometry = geometry_importance(pts, s, e) > T
    assert geometry.sum() <= kept.size < 0.75 * union.sum(), (geometry.sum(), kept.size, union.sum())


def test_non_finite_mapped_values_and_their_neighbours_are_kept():
    n = 200
    pts = np.c_[np.linspace(0, 1, n), np.zeros(n), np.zeros(n)]
    s, e = np.array([0]), np.array([n])
    arc = arc_parameter(pts, s, e)
    v = np.linspace(0, 1, n)
    v[[50, 120]] = np.nan
    # kept: the run's ends, each NaN point and its neighbours (the segments next to a NaN have
    # no colour); the straight stretches between them need no more
    imp = lod_importance(pts, arc, s, e, (), [(v, slopes(v, arc, s, e), 0.1)])
    assert set(np.flatnonzero(imp > 1e30)) == {0, 49, 50, 51, 119, 120, 121, n - 1}


def test_slopes_are_pchips_and_zero_at_extrema():
    from scipy.interpolate import PchipInterpolator
    x = np.sort(np.random.default_rng(1).uniform(0, 3, 200))
    pts = np.c_[x, np.zeros_like(x), np.zeros_like(x)]
    v = np.sin(2 * x) + 0.1 * x
    s, e = np.array([0]), np.array([x.size])
    m = slopes(v, arc_parameter(pts, s, e), s, e)
    ref = PchipInterpolator(x, v).derivative()(x)
    np.testing.assert_allclose(m, ref, rtol=1e-9, atol=1e-12)
    ext = np.flatnonzero(np.diff(np.sign(np.diff(v)))) + 1  # discrete local extrema
    assert ext.size == 2 and np.all(m[ext] == 0.0)


def test_no_points_nan_points_and_single_point_lines_render():
    s = style(Band(BLACK, 2.0), Band((1, 0, 0, 1), 1.0, depth_offset=0.1), background=WHITE)
    empty = render_lines(Lines(np.zeros((0, 3)), [0]), s, (32, 16))
    assert (empty == 255).all()
    nan = render_lines(Lines(np.full((3, 3), np.nan), [0, 3]), s, (32, 16))
    assert (nan == 255).all()
    p = np.c_[np.linspace(-1, 1, 20), np.zeros(20), np.zeros(20)]
    p[10] = np.nan  # a gap: two runs; the first line is a single point (not drawn)
    with LineRenderer(Lines(p, [0, 1, 20])) as r:
        img = r.render(s, (64, 32), FACE_ON)
        assert r.n_drawn == 4  # both ends of the two straight runs
    ink = np.any(img[:, :, :3] < 128, axis=2)
    assert ink[:, 20].any() and ink[:, 44].any() and not ink[:, 32].any()  # the gap stays open


def test_tolerance_argument_is_checked():
    with pytest.raises(ValueError, match="tolerance = -1"):
        LineRenderer(helices(1, 10), tolerance=-1)


# the bounding-sphere framing the pixel figures below were measured at
@pytest.mark.parametrize("cam", [Camera(up=(0, 0, 1), fit="sphere"), Camera(azimuth=20, elevation=40,
                                                              projection="orthographic")])
def test_pictures_with_and_without_level_of_detail_agree(cam):
    lines = helices(12, 3000)  # ~0.1-pixel segments at this size
    s = style(Band(ColorMap("viridis", "speed", (0, 1)), 2.0),
              Band(BLACK, 1.5, depth_offset=0.15), background=WHITE, antialias="none")
    with LineRenderer(lines, tolerance=0.0) as full, LineRenderer(lines) as lod:
        a = full.render(s, (320, 240), cam)
        b = lod.render(s, (320, 240), cam)
        assert lod.n_indices < full.n_indices / 8
    diff = np.abs(a.astype(int) - b.astype(int)).max(axis=2)
    ink = np.mean(np.any(a[..., :3] != 255, axis=2))
    assert ink > 0.2
    # 0.25-px moves flip a few edge pixels (measured 0.2-0.4 %); colours agree to a few levels
    assert np.mean(diff > 8) < 0.01, np.mean(diff > 8)
    assert diff.mean() < 1.0, diff.mean()


def test_frames_reselect_only_when_the_view_changes():
    lines = helices(3, 500)
    s = style(Band(BLACK, 2.0), background=WHITE, antialias="none")
    with LineRenderer(lines) as r:
        r.render(s, (100, 80), FACE_ON)
        key, n = r._frame_key, r.n_indices
        r.render(s, (100, 80), FACE_ON)
        assert r._frame_key is key
        r.render(s, (400, 320), FACE_ON)  # 4x larger: more detail
        assert r._frame_key is not key and r.n_indices > n
    with LineRenderer(lines, tolerance=0) as r:  # every vertex: nothing depends on the camera
        r.render(s, (100, 80), FACE_ON)
        key, n = r._frame_key, r.n_indices
        r.render(s, (400, 320), Camera(azimuth=10))
        assert r._frame_key is key and r.n_indices == n == 3 * (2 * 500 + 1)


def test_mapped_attribute_points_drop_where_their_colours_move_less_than_the_tolerance():
    # a colormapped attribute changing fast along a straight line: a point whose value the
    # interpolant misses by more than half a LUT step is still dropped when the colours
    # around it move along the line by less than the pixel tolerance, so a line shown smaller
    # keeps fewer points (a value tolerance alone keeps the same ones at every size)
    n = 4000
    x = np.linspace(-1, 1, n)
    lines = Lines(np.c_[x, np.zeros(n), np.zeros(n)], [0, n], {"v": np.sinh(3 * x) + np.sin(12 * x)})
    s = style(Band(ColorMap("viridis", "v", (-10, 10)), 3.0), background=WHITE, antialias="none")
    value_only = None
    kept = []
    for zoom, size in [(2.9, (400, 60)), (1.0, (100, 30))]:
        cam = dataclasses.replace(FACE_ON, zoom=zoom)
        with LineRenderer(lines, tolerance=0.0) as full, LineRenderer(lines) as lod:
            a, b = full.render(s, size, cam), lod.render(s, size, cam)
            kept.append(lod.n_drawn)
            v = lines.point_data["v"]
            m = slopes(v, lod._arc, lod._starts, lod._stops)
            value_only = int(np.sum(attribute_importance(v, m, lod._arc, lod._starts, lod._stops)
                                    > 0.5 * 20 / 512))
        diff = np.abs(a.astype(int) - b.astype(int)).max(axis=2)
        assert np.any(a[..., :3] != 255)
        assert diff.max() <= 4, diff.max()  # colours shifted by < 0.25 px along the line
    assert kept[1] < kept[0] <= value_only + 2


def test_split_by_range_puts_every_segment_in_exactly_one_strip_piece():
    from flowkit.render.simplify import RESTART, adjacency, split_by_range

    # two runs of 6 and 5 points; values cross the bound 0.5 between points, one NaN
    pts = np.c_[np.arange(11.0), np.zeros(11), np.zeros(11)]
    lines = Lines(pts, [0, 6, 11])
    s, e = runs(lines)
    v = np.array([0.1, 0.2, 0.7, 0.8, 0.9, 0.3, 0.6, 0.7, np.nan, 0.1, 0.2], np.float32)
    ids, idx = select(pts, geometry_importance(pts, s, e), np.eye(4), (0.0, 1.0), 0.0,
                      np.zeros(0, bool), s, e)  # tolerance 0: every point
    out, counts = split_by_range(idx, ids, v, [-1e30, 0.5], [0.5, 1e30])
    assert counts.sum() == out.size and len(counts) == 3
    # range 0 (< 0.5), range 1 (>= 0.5), mixed: crossing the bound or touching the NaN
    want = {0: {(0, 1), (9, 10)}, 1: {(2, 3), (3, 4), (6, 7)}, 2: {(1, 2), (4, 5), (7, 8), (8, 9)}}
    first = 0
    for g, c in enumerate(counts):
        part = out[first:first + c]
        first += c
        assert RESTART not in part  # the pieces of a group are joined into one strip
        # each piece: both strip vertices of consecutive points; the segments it draws
        quads = adjacency(part).reshape(-1, 4)
        got = {(int(ids[q[1]]), int(ids[q[2]])) for q in quads}
        assert got == want[g], (g, got)
        # neighbours are those of the whole run, across piece ends (continuous joins)
        for q in quads:
            a, b = ids[q[1]], ids[q[2]]
            assert ids[q[0]] == (a - 1 if a not in (0, 6) else -1)
            assert ids[q[3]] == (b + 1 if b not in (5, 10) else -1)


@pytest.mark.parametrize("seed", range(4))
def test_select_and_split_match_a_point_by_point_reference_on_random_runs(seed):
    # both run in passes (select in parallel over runs): the layout must be the one a plain
    # loop over the points gives, with -1 between runs and a restart after each
    from flowkit.render.simplify import RESTART, split_by_range

    rng = np.random.default_rng(seed)
    lens = rng.integers(1, 40, 30)
    lines = Lines(rng.normal(size=(lens.sum(), 3)), np.r_[0, np.cumsum(lens)])
    s, e = runs(lines)
    imp = rng.uniform(0.0, 2.0, lines.n_points).astype(np.float32)
    extra = rng.random(lines.n_points) < 0.1
    px = (0.1, 1.0)
    ids, idx = select(lines.points, imp, np.eye(4), px, 1.0, extra, s, e)
    z = lines.points[:, 2]
    want_ids, want_idx = [-1], []
    for a, b in zip(s, e):
        for i in range(a, b):
            if i in (a, b - 1) or extra[i] or imp[i] > 0.5 * (px[0] * -z[i] + px[1]):
                want_idx += [2 * (len(want_ids) - 1), 2 * (len(want_ids) - 1) + 1]
                want_ids.append(i)
        want_ids.append(-1)
        want_idx.append(RESTART)
    assert ids.tolist() == np.repeat(want_ids, 2).tolist() + [-1] * 4
    assert idx.tolist() == want_idx
    # every drawn segment in the group its two end values give, pieces in drawing order,
    # each group one strip
    v = rng.choice(np.array([0.1, 0.4, 0.6, 0.9, np.nan], np.float32), lines.n_points)
    lo, hi = [-1e30, 0.5], [0.5, 1e30]
    out, counts = split_by_range(idx, ids, v, lo, hi)
    want = [[] for _ in range(3)]
    for a, b in zip(s, e):
        kept = [i for i in range(a, b) if i in ids]
        group = [next((r for r in range(2) if all(lo[r] <= v[j] < hi[r] for j in seg)), 2)
                 for seg in itertools.pairwise(kept)]
        for g in range(3):  # consecutive segments of one group form one piece
            k = 0
            while k < len(group):
                if group[k] != g:
                    k += 1
                    continue
                m = k
                while m < len(group) and group[m] == g:
                    m += 1
                first = 2 * (want_ids.index(kept[k]) - 1)
                if want[g]:  # joined to the group's previous piece: two zero-area triangles
                    want[g] += [want[g][-1], first]
                for i in kept[k:m + 1]:
                    el = 2 * (want_ids.index(i) - 1)
                    want[g] += [el, el + 1]
                k = m
    assert counts.tolist() == [len(w) for w in want]
    assert out.tolist() == want[0] + want[1] + want[2]


def test_world_unit_width_maps_do_not_redo_the_level_of_detail_each_frame(monkeypatch):
    # a width map in world units has a value tolerance that follows the pixel size: rounded to
    # a power of 2, a turning camera reuses it instead of running a DP over every point per frame
    import flowkit.render.renderer as R
    calls = []
    real = R.lod_importance
    monkeypatch.setattr(R, "lod_importance", lambda *a: calls.append(a[-1]) or real(*a))
    lines = helices(6, 400)
    s = style(Band((0, 0, 0, 1), WidthMap("speed", (0.0, 1.0), 0.01, 0.05)), units="world")
    with LineRenderer(lines) as r:
        for k in range(8):
            r.render(s, (160, 120), Camera(azimuth=30 + 0.2 * k))
        assert r.n_drawn > 0
    assert 1 <= len(calls) <= 2, calls
    assert len(r._lods) <= R.LOD_KEPT


def test_finite_rows_is_numpys_all_of_isfinite():
    """``lines.finite_rows`` (the runs, the picker's index, the bounds) is
    np.all(np.isfinite(p), axis=1) for a non-finite value in any column."""
    from flowkit.lines import finite_rows

    p = np.random.default_rng(2).standard_normal((3000, 3))
    bad = np.random.default_rng(3).integers(0, 3000, (300, 2))
    p[bad[:, 0], bad[:, 1] % 3] = np.resize([np.nan, np.inf, -np.inf], 300)
    np.testing.assert_array_equal(finite_rows(p), np.all(np.isfinite(p), axis=1))
    assert not finite_rows(p).all() and finite_rows(p).any()
