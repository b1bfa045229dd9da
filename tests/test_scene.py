"""Scenes: the attributes traced are exactly those the drawn styles read; a style-only change
re-renders from the cache without tracing (counted, not timed); a changed field file or option
traces again; --explain says what and why; bad scene files get errors naming key and value; a
scene over a series gives one image per snapshot; the demo scene plans what its styles read."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

import flowkit.integrate.attributes as attributes_mod
import flowkit.integrate.trace as trace_mod
import flowkit.scene.plan as plan_mod
from flowkit.cli import main
from flowkit.fields import Field, Grid
from flowkit.fields.writers import save_field, save_series
from flowkit.io.lines_h5 import read_lines
from flowkit.scene import SceneError, load_scene, make_plan, run_scene

ROOT = Path(__file__).resolve().parents[1]
SIZE = "[96, 64]"


def swirl(omega=1.0, rise=0.3, n=13) -> Field:
    """Rotation about z with a rise along z on [-1, 1]^3, temperature T = 300 + z, p = x."""
    g = Grid.regular((-1.0, -1.0, -1.0), (2 / (n - 1),) * 3, (n, n, n))
    x, y, z = np.meshgrid(g.x, g.y, g.z, indexing="ij")
    v = np.stack([-omega * y, omega * x, np.full_like(x, rise)], axis=-1)
    return Field(g, v, {"T": 300.0 + z, "p": x.copy()}, source="swirl")


def write_scene(tmp_path: Path, styles: str, views: str = "", trace: str = "",
                field: str = 'file = "field.h5"', outputs: str = "", name="scene.toml") -> Path:
    text = textwrap.dedent(f"""\
        version = 1
        [field]
        {field}
        [seeds]
        spec = "line:0.2,0,-0.9:0.7,0,-0.9:4"
        [trace]
        max_length = 3.0
        direction = "both"
        {trace}
        [styles]
        """) + textwrap.dedent(styles) + textwrap.dedent(views) + textwrap.dedent(outputs)
    p = tmp_path / name
    p.write_text(text)
    return p


PLAIN = """\
    [styles.plain]
    [[styles.plain.bands]]
    color = "#203060"
    width = 2
    """
SPEED = """\
    [styles.fast]
    [[styles.fast.bands]]
    color = { cmap = "viridis", attribute = "speed", range = [0, 1.2] }
    width = 2
    [[styles.fast.bands]]
    color = "#000000"
    width = 1
    depth_offset = 0.02
    """
# width mapped from vorticity_magnitude, colour from nothing: an attribute no colour displays
WIDTH_ONLY = """\
    [styles.swirly]
    [[styles.swirly.bands]]
    color = "#aa2020"
    width = { attribute = "vorticity_magnitude", range = [0, 2], min = 1, max = 3 }
    """

# a transfer function on T (which no band displays) picks 'cold' or 'warm'; 'warm' colours by
# speed; 'unused' reads p but no range picks it, so p is not traced
TRANSFER = """\
    [styles.tf.transfer]
    attribute = "T"
    ranges = [{ range = [-inf, 299.5], style = "cold" }, { range = [299.5, inf], style = "warm" }]
    [[styles.tf.styles.cold.bands]]
    color = "#2040a0"
    width = 2
    [[styles.tf.styles.warm.bands]]
    color = { cmap = "magma", attribute = "speed", range = [0, 1.2] }
    width = 2
    [[styles.tf.styles.unused.bands]]
    color = { cmap = "gray", attribute = "p", range = [-1, 1] }
    """


@pytest.fixture
def field_file(tmp_path):
    return save_field(swirl(), tmp_path / "field.h5")


@pytest.fixture
def spy(monkeypatch):
    """Counts calls into the integrator, field loading, the curl and scalar sampling."""
    calls = {"trace": [], "load": 0, "curl": 0, "scalar": []}
    real_trace, real_load = trace_mod.trace, plan_mod.load_field
    real_curl, real_scalar = attributes_mod.vorticity_at, Field.sample_scalar
    real_with = Field.sample_with

    def trace(field, seeds, options=None, **kw):
        calls["trace"].append(tuple(options.attributes))
        return real_trace(field, seeds, options, **kw)

    def load(*a, **kw):
        calls["load"] += 1
        return real_load(*a, **kw)

    def curl(field, points):  # the vorticity (the node curl at the vertices' cells)
        calls["curl"] += 1
        return real_curl(field, points)

    def sample_scalar(self, name, points):
        calls["scalar"].append(name)
        return real_scalar(self, name, points)

    def sample_with(self, name, points):  # the vector and a scalar in one pass
        calls["scalar"].append(name)
        return real_with(self, name, points)

    monkeypatch.setattr(trace_mod, "trace", trace)
    monkeypatch.setattr(plan_mod, "load_field", load)
    monkeypatch.setattr(attributes_mod, "vorticity_at", curl)
    monkeypatch.setattr(Field, "sample_scalar", sample_scalar)
    monkeypatch.setattr(Field, "sample_with", sample_with)
    return calls


def run(path, **kw):
    kw.setdefault("report", None)
    return run_scene(path, **kw)


# -- only what the styles read ----------------------------------------------------------------
SCENES = {
    # styles, views, extra trace keys -> traced attributes, curl computed, scalars sampled
    "plain": (PLAIN, "", "", (), 0, []),
    "colormap": (SPEED, "", "", ("speed",), 0, []),
    "width_only": (WIDTH_ONLY, "", "", ("vorticity_magnitude",), 1, []),
    # a file reference: grey colormap on T, width from speed (examples/styles)
    "referenced": (f'tw = "{ROOT / "examples/styles/temperature_width.toml"}"\n', "", "",
                   ("T", "speed"), 0, ["T"]),
    # two styles defined, one view draws only 'fast': the T style costs nothing
    "unused_style": (SPEED + WIDTH_ONLY.replace("vorticity_magnitude", "T"),
                     f'[views.only]\nstyle = "fast"\nsize = {SIZE}\n', "", ("speed",), 0, []),
    # per-line data (reason) is stored anyway: nothing extra traced
    "line_data": (("[styles.why]\n[[styles.why.bands]]\n"
                   'color = { cmap = "viridis", attribute = "reason", range = [0, 8] }\n'), "", "",
                  (), 0, []),
    "transfer": (TRANSFER, "", "", ("T", "speed"), 0, ["T"]),
    # [trace] attributes adds to what the styles read, for the lines file
    "extra": (SPEED, "", 'attributes = ["p"]', ("speed", "p"), 0, ["p"]),
}


@pytest.mark.parametrize("name", sorted(SCENES))
def test_attributes_traced_are_exactly_those_the_styles_read(tmp_path, field_file, spy, name):
    styles, views, trace, want, curls, scalars = SCENES[name]
    views = views or f"[views.main]\nsize = {SIZE}\n"
    path = write_scene(tmp_path, styles, views, trace, outputs='[outputs]\nlines = "l.h5"\n'
                       'images = "{view}.png"\n')
    scene = load_scene(path)
    assert make_plan(scene).attributes == want
    res = run(path)
    assert spy["trace"] == [want]
    assert set(read_lines(tmp_path / "l.h5").point_data) == set(want)
    assert spy["curl"] == curls
    assert sorted(set(spy["scalar"])) == sorted(scalars)
    assert len(res.snapshots[0].images) == len(scene.views)
    # the GPU gets what the drawn styles read: not [trace] attributes, but per-line data they map
    drawn = {a for v in scene.views.values() for a in scene.styles[v.style].attributes()}
    assert set(res.snapshots[0].uploaded) == drawn
    assert drawn == set(want) - {"p"} | ({"reason"} if name == "line_data" else set())


def test_vector_attribute_in_a_style_is_refused(tmp_path, field_file):
    styles = SPEED.replace('"speed"', '"velocity"')
    with pytest.raises(SceneError, match="'velocity', a 3-component attribute.*use speed"):
        make_plan(load_scene(write_scene(tmp_path, styles)))


# -- the cache ----------------------------------------------------------------------------------
def test_style_or_camera_change_rerenders_from_cache_without_tracing(tmp_path, field_file, spy):
    view = f'[views.main]\nsize = {SIZE}\ncamera = {{ azimuth = -60, elevation = 20 }}\n'
    lines_out = '[outputs]\nlines = "l.h5"\n'
    path = write_scene(tmp_path, SPEED, view, outputs=lines_out)
    first = run(path)
    written = (tmp_path / "l.h5").stat()
    assert [s.action for s in first.snapshots] == ["trace"] and len(spy["trace"]) == 1
    img1 = Path(first.snapshots[0].images["main"]).read_bytes()

    write_scene(tmp_path, SPEED.replace("viridis", "magma").replace("width = 2", "width = 3"),
                view.replace("-60", "30"), outputs=lines_out)
    second = run(path)
    assert [s.action for s in second.snapshots] == ["hit"]
    assert len(spy["trace"]) == 1 and spy["load"] == 1  # no trace, not even a field load
    assert Path(second.snapshots[0].images["main"]).read_bytes() != img1  # it did re-render
    # the lines file already holds these lines: not rewritten
    again = (tmp_path / "l.h5").stat()
    assert (again.st_ino, again.st_mtime_ns) == (written.st_ino, written.st_mtime_ns)


def test_changed_field_content_or_option_misses_the_cache(tmp_path, field_file, spy):
    path = write_scene(tmp_path, SPEED)
    assert run(path).snapshots[0].action == "trace"
    # the same bytes written again (new mtime): content hash, so still a hit
    field_file.write_bytes(field_file.read_bytes())
    assert run(path).snapshots[0].action == "hit"
    save_field(swirl(omega=1.5), field_file)
    assert run(path).snapshots[0].action == "trace"
    write_scene(tmp_path, SPEED, trace="rtol = 1e-8")
    assert run(path).snapshots[0].action == "trace"
    write_scene(tmp_path, SPEED, trace="rtol = 1e-8").write_text(
        path.read_text().replace("0.7,0,-0.9:4", "0.7,0,-0.9:5"))
    assert run(path).snapshots[0].action == "trace"
    assert len(spy["trace"]) == 4
    assert run(path, use_cache=False).snapshots[0].action == "trace" and len(spy["trace"]) == 5


def test_changed_line_making_code_misses_the_cache(tmp_path, field_file, spy, monkeypatch):
    """A checkout between releases keeps flowkit's version but not its lines: the key holds a
    digest of the readers', integrators' and lines file's source, not of the renderer's."""
    from flowkit.scene import cache

    path = write_scene(tmp_path, SPEED)
    assert run(path).snapshots[0].action == "trace"
    assert run(path).snapshots[0].action == "hit"
    monkeypatch.setattr(cache, "code_digest", lambda: "an integrator fix")
    assert run(path).snapshots[0].action == "trace" and len(spy["trace"]) == 2
    monkeypatch.undo()
    real = cache.code_digest()
    assert len(real) == 32 and real == cache.code_digest()
    for name in cache.LINE_MAKERS:
        assert (Path(cache.__file__).parent.parent / name).exists(), name


def test_a_new_attribute_is_added_on_cached_vertices_or_retraced(tmp_path, field_file, spy):
    path = write_scene(tmp_path, SPEED, outputs='[outputs]\nlines = "l.h5"\n')
    run(path)
    # T on top of speed: computed on the cached vertices, no trace ...
    t_style = SPEED.replace('color = "#000000"', 'color = { cmap = "gray", attribute = "T", '
                            'range = [299, 301] }')
    write_scene(tmp_path, t_style, outputs='[outputs]\nlines = "l.h5"\n')
    res = run(path)
    assert res.snapshots[0].action == "extend" and len(spy["trace"]) == 1
    extended = read_lines(tmp_path / "l.h5")
    # ... and equal to what a trace that asked for it gives
    plan = make_plan(load_scene(path))
    fld = swirl()
    fresh = trace_mod.trace(fld, plan.seed_points(fld), plan.options)
    np.testing.assert_array_equal(extended.point_data["T"], fresh.point_data["T"])
    assert run(path).snapshots[0].action == "hit"
    # time comes from the integrator only: re-trace, and say so
    write_scene(tmp_path, t_style.replace('"speed"', '"time"'))
    assert "only the integrator gives: re-trace" in make_plan(load_scene(path)).explain(
        _cache(path))
    res = run(path)
    assert res.snapshots[0].action == "retrace" and spy["trace"][-1] == ("time", "T")


def test_one_more_attribute_is_sampled_onto_the_cached_entry(tmp_path, field_file, spy):
    """A style that reads one attribute more than the cached lines hold: the entry's vertices
    get it (flowkit.sample, which says how many came out NaN), no trace, the same entry."""
    from flowkit.integrate.sample import nan_counts

    path = write_scene(tmp_path, SPEED, outputs='[outputs]\nlines = "l.h5"\n')
    run(path)
    entries = sorted(_cache(path).dir.glob("*.json"))
    wider = SPEED.replace("width = 2", 'width = { attribute = "distance_to_seed", range = '
                          "[0, 3], min = 1, max = 3 }")
    write_scene(tmp_path, wider, outputs='[outputs]\nlines = "l.h5"\n')
    res = run(path)
    assert res.snapshots[0].action == "extend" and len(spy["trace"]) == 1
    assert sorted(_cache(path).dir.glob("*.json")) == entries  # the entry itself, extended
    cache = _cache(path)
    entry = cache.get(entries[0].stem)
    assert set(entry.point_attributes) == {"speed", "distance_to_seed"}
    got = read_lines(tmp_path / "l.h5")
    assert nan_counts(got) == {"distance_to_seed": 0}
    # the values a trace that asked for both gives, from the seeds (the lines hold only seed_id)
    assert "seed" not in got.line_data
    plan = make_plan(load_scene(path))
    fresh = trace_mod.trace(swirl(), plan.seed_points(swirl()), plan.options)
    for name in ("speed", "distance_to_seed"):
        np.testing.assert_array_equal(cache.read(entry).point_data[name],
                                      fresh.point_data[name], err_msg=name)
    assert run(path).snapshots[0].action == "hit" and len(spy["trace"]) == 2  # (fresh above)


def _cache(path):
    from flowkit.scene import LinesCache

    return LinesCache(load_scene(path).cache_dir)


# -- --explain ----------------------------------------------------------------------------------
def test_explain_says_what_is_computed_and_why(tmp_path, field_file, capsys, spy):
    path = write_scene(tmp_path, SPEED + WIDTH_ONLY.replace("vorticity_magnitude", "T"),
                       f'[views.side]\nstyle = "fast"\nsize = {SIZE}\n'
                       f'[views.top]\nstyle = "fast"\nsize = {SIZE}\n')
    assert main(["scene", str(path), "--explain"]) == 0
    out = capsys.readouterr().out
    assert "attributes traced: speed\n" in out
    assert "  speed: field sampled at every vertex (trilinear)" in out
    assert "    read by view 'side': style 'fast' band 1 colour (viridis)" in out
    assert "    read by view 'top': style 'fast' band 1 colour (viridis)" in out
    assert ("not computed (no style reads it): vorticity curl (vorticity, "
            "vorticity_magnitude); scalar field sampling (e.g. T)") in out
    assert "style 'swirly': inline  -- drawn by no view: nothing traced for it" in out
    assert "  snapshot 0: miss: trace" in out
    assert spy["trace"] == [] and not (tmp_path / "side_0.png").exists()  # explained, not run
    assert main(["scene", str(path)]) == 0
    capsys.readouterr()
    assert main(["scene", str(path), "--explain"]) == 0
    assert "  snapshot 0: hit: lines and attributes cached, no tracing" in capsys.readouterr().out
    # a transfer function: its attribute, then the bands of the line styles it picks
    tf = write_scene(tmp_path, SPEED + TRANSFER, f'[views.side]\nstyle = "fast"\nsize = {SIZE}\n'
                     f'[views.top]\nstyle = "tf"\nsize = {SIZE}\n', name="tf.toml")
    assert main(["scene", str(tf), "--explain"]) == 0
    out = capsys.readouterr().out
    assert "attributes traced: speed, T\n" in out
    assert "    read by view 'top': style 'tf' transfer function" in out
    assert "    read by view 'top': style 'tf' line style 'warm' band 1 colour (magma)" in out
    assert "'p'" not in out and "unused" not in out


# -- bad scene files ----------------------------------------------------------------------------
OK_FIELD = '[field]\nfile = "field.h5"\n'
OK_SEEDS = '[seeds]\nspec = "line:0,0,0:0.5,0,0:3"\n'
OK_STYLES = "[styles.a]\n[[styles.a.bands]]\nwidth = 2\n"
OK = OK_FIELD + OK_SEEDS + OK_STYLES
ANIM = '[outputs]\nanimation = "a.gif"\n'
BAD = {
    "no_version": (OK, ["missing key 'version'"]),
    "version_2": ("version = 2\n" + OK, ["version = 2", "expected 1"]),
    "unknown_top": ("version = 1\nfeild = 1\n" + OK, ["unknown key 'feild'", "allowed keys"]),
    "no_field": ("version = 1\n" + OK_SEEDS + OK_STYLES, ["missing table [field]"]),
    "two_sources": ('version = 1\n[field]\nfile = "field.h5"\ndataset = "hotroom"\n' + OK_SEEDS
                    + OK_STYLES, ["[field]", "exactly one of file, series or dataset"]),
    "missing_file": ('version = 1\n[field]\nfile = "nope.h5"\n' + OK_SEEDS + OK_STYLES,
                     ["[field]", "file = 'nope.h5'", "an existing file"]),
    "dataset": ('version = 1\n[field]\ndataset = "attic"\n' + OK_SEEDS + OK_STYLES,
                ["dataset = 'attic'", "'hotroom'"]),
    "snapshot": ('version = 1\n[field]\nfile = "field.h5"\nsnapshot = "last"\n' + OK_SEEDS
                 + OK_STYLES, ["snapshot = 'last'", "'all', a snapshot position"]),
    "field_key": ('version = 1\n[field]\nfile = "field.h5"\nvectr = "U"\n' + OK_SEEDS
                  + OK_STYLES, ["[field]", "unknown key 'vectr'", "vector"]),
    "seed_spec": ("version = 1\n" + OK_FIELD + '[seeds]\nspec = "plane:0,0,0:1,0,0:3"\n'
                  + OK_STYLES, ["[seeds]", "spec = 'plane:0,0,0:1,0,0:3'", "takes 4 parts"]),
    "trace_key": ("version = 1\n" + OK + "[trace]\nrtoll = 1e-6\n",
                  ["[trace]", "unknown key 'rtoll'", "rtol"]),
    "trace_value": ("version = 1\n" + OK + "[trace]\nrtol = -1\n",
                    ["[trace]", "rtol = -1", "must be positive"]),
    "trace_direction": ("version = 1\n" + OK + '[trace]\ndirection = "sideways"\n',
                        ["direction = 'sideways'", "forward"]),
    "trace_bool": ("version = 1\n" + OK + "[trace]\nmax_length = true\n",
                   ["max_length = True", "a number"]),
    "style_band": ("version = 1\n" + OK_FIELD + OK_SEEDS
                   + "[styles.a]\n[[styles.a.bands]]\nwidth = -2\n",
                   ["[styles.a]", "band 1", "width = -2", ">= 0"]),
    "style_cmap": ("version = 1\n" + OK_FIELD + OK_SEEDS + "[styles.a]\n[[styles.a.bands]]\n"
                   "color = { cmap = 'nocmap_x', attribute = 'T', range = [0, 1] }\n",
                   ["[styles.a]", "color.cmap = 'nocmap_x'"]),
    "style_file": ("version = 1\n" + OK_FIELD + OK_SEEDS + '[styles]\na = "missing.toml"\n',
                   ["[styles]", "a = 'missing.toml'", "a style file that exists"]),
    "view_style": ("version = 1\n" + OK + '[views.v]\nstyle = "b"\n',
                   ["[views.v]", "style = 'b'", "one of the scene's styles: a"]),
    "view_size": ("version = 1\n" + OK + "[views.v]\nsize = [0, 10]\n",
                  ["[views.v]", "size = [0, 10]", "[width, height]"]),
    "view_camera": ("version = 1\n" + OK + "[views.v]\ncamera = { elevation = 400 }\n",
                    ["[views.v].camera", "elevation = 400", "<= 360"]),
    "view_key": ("version = 1\n" + OK + "[views.v]\nzoom = 2\n",
                 ["[views.v]", "unknown key 'zoom'", "camera"]),
    "image_pattern": ("version = 1\n" + OK + '[outputs]\nimages = "{veiw}.png"\n',
                      ["[outputs]", "images = '{veiw}.png'", "{view}", "not {veiw}"]),
    "two_views_one_name": ("version = 1\n" + OK + "[views.v]\n[views.w]\n"
                           '[outputs]\nimages = "same.png"\n',
                           ["images = 'same.png'", "with {view}", "2 views"]),
    "lines_pattern": ("version = 1\n" + OK + '[outputs]\nlines = "{view}.h5"\n',
                      ["lines = '{view}.h5'", "{snapshot}, {time}"]),
    "outputs_key": ("version = 1\n" + OK + '[outputs]\nmovie = "a.gif"\n',
                    ["unknown key 'movie'", "animation, fps, frames, images, lines"]),
    "frames_zero": ("version = 1\n" + OK + ANIM + "frames = 0\n",
                    ["[outputs]", "frames = 0", "an integer from 1 to 100000"]),
    "frames_negative": ("version = 1\n" + OK + ANIM + "frames = -1\n",
                        ["[outputs]", "frames = -1", "an integer from 1 to 100000"]),
    "frames_string": ("version = 1\n" + OK + ANIM + 'frames = "x"\n',
                      ["[outputs]", "frames = 'x'", "an integer from 1 to 100000"]),
    "fps_zero": ("version = 1\n" + OK + ANIM + "fps = 0\n", ["[outputs]", "fps = 0", "> 0"]),
    "animation_suffix": ("version = 1\n" + OK + '[outputs]\nanimation = "a.avi"\n',
                         ["[outputs]", "animation = 'a.avi'", ".png, .gif, .mp4"]),
    "animation_pattern": ("version = 1\n" + OK + '[outputs]\nanimation = "{veiw}.gif"\n',
                          ["animation = '{veiw}.gif'", "not {veiw}"]),
    "animation_two_views": ("version = 1\n" + OK + "[views.v]\n[views.w]\n"
                            '[outputs]\nimages = "{view}.png"\nanimation = "a.gif"\n',
                            ["animation = 'a.gif'", "with {view}", "2 views"]),
    "frames_alone": ("version = 1\n" + OK + "[outputs]\nframes = 8\n",
                     ["[outputs]", "frames = 8", "without animation"]),
    "not_toml": ("version = 1\n[field\n", ["not valid TOML"]),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_scene_file_gets_its_error(tmp_path, field_file, capsys, name):
    text, parts = BAD[name]
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    with pytest.raises(SceneError) as e:
        load_scene(path)
    msg = str(e.value)
    assert str(path) in msg
    for p in parts:
        assert p in msg, f"{p!r} not in {msg!r}"
    # the CLI prints it as one line, status 2
    assert main(["scene", str(path), "--explain"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("flowkit scene: error: ") and err.count("\n") == 1


def test_snapshot_out_of_range_is_named(tmp_path, field_file):
    path = write_scene(tmp_path, PLAIN, field='file = "field.h5"\nsnapshot = 3')
    with pytest.raises(SceneError, match=r"snapshot = 3 is not allowed.*has 1 snapshot"):
        make_plan(load_scene(path))


# -- animation ----------------------------------------------------------------------------------
# arrows moving along the lines plus a two-colour pattern: every frame differs from the others
MOVING = """\
    [styles.arrows]
    antialias = "none"
    [[styles.arrows.bands]]
    color = "#ffff00"
    width = 3
    shape = { name = "arrow", length = 0.6 }
    pattern = { color = "#0000ff", length = 0.6 }
    """
TWO_VIEWS = (f'[views.moving]\nstyle = "arrows"\nsize = {SIZE}\n'
             f'[views.still]\nstyle = "plain"\nsize = {SIZE}\n')
ANIMATION = '[outputs]\nimages = "{view}.png"\nanimation = "{view}_{snapshot}.gif"\nframes = 4\n'


def test_animation_output_writes_moving_frames_after_the_stills(tmp_path, field_file, spy,
                                                                capsys):
    from PIL import Image

    path = write_scene(tmp_path, MOVING + PLAIN, TWO_VIEWS, outputs=ANIMATION + "fps = 10\n")
    log = []
    res = run(path, report=log.append)
    snap = res.snapshots[0]
    gif = Image.open(snap.animations["moving"][0])
    assert snap.animations["moving"] == [tmp_path / "moving_0.gif"]
    assert gif.n_frames == 4 and gif.info["duration"] == 100 and gif.size == (96, 64)
    frames = []
    for k in range(4):
        gif.seek(k)
        frames.append(np.asarray(gif.convert("RGB")))
    assert len({f.tobytes() for f in frames}) == 4  # the arrows moved in every frame
    # the still view is not animated, and the run says why (a still loop would be 4 equal frames)
    assert "still" not in snap.animations and not (tmp_path / "still_0.gif").exists()
    warning = [m for m in log if m.startswith("warning:")]
    assert warning == [("warning: no animation for view 'still': style 'plain' has no band "
                        "'shape' or 'pattern' to move, so every frame would be the same picture "
                        "(stills only)")]
    # progress like the other stages, the animation after the still images
    stages = [m.split("] ", 1)[1].split(":")[0] for m in log if m.startswith("[1/1")]
    assert list(dict.fromkeys(stages))[-3:] == ["render moving", "render still", "animate moving"]
    assert [m for m in log if ": frame " in m] == [f"[1/1 snapshot 0 t=0] animate moving: frame {k}/4"
                                                 for k in (1, 2, 3)]
    assert "moving_0.gif (4 frames at 10 fps, 96x64)" in log[-2]
    assert log[-1].startswith("scene done: 1 snapshot(s), 2 image(s), 1 animation(s)")
    # numbered PNG frames through the CLI, from the cache; frame 0 is the still picture
    write_scene(tmp_path, MOVING + PLAIN, TWO_VIEWS,
                outputs=ANIMATION.replace(".gif", ".png").replace("4", "3"))
    assert main(["scene", str(path)]) == 0
    cap = capsys.readouterr()
    assert "animate moving: " in cap.err and len(spy["trace"]) == 1
    assert f"wrote {tmp_path / 'moving_0_0002.png'}" in cap.out.splitlines()
    names = sorted(p.name for p in tmp_path.glob("moving_0_*.png"))
    assert names == ["moving_0_0000.png", "moving_0_0001.png", "moving_0_0002.png"]
    first = np.asarray(Image.open(tmp_path / "moving_0_0000.png"))
    np.testing.assert_array_equal(first, np.asarray(Image.open(tmp_path / "moving.png")))
    assert not np.array_equal(first, np.asarray(Image.open(tmp_path / "moving_0_0001.png")))


def test_explain_mentions_the_animation(tmp_path, field_file, capsys, spy):
    path = write_scene(tmp_path, MOVING + PLAIN, TWO_VIEWS, outputs=ANIMATION)
    assert main(["scene", str(path), "--explain"]) == 0
    out = capsys.readouterr().out
    assert ("animation: {view}_{snapshot}.gif, 4 frames at 12 fps (the shapes and patterns move "
            "one period), rendered after the stills for view 'moving'") in out
    assert "  warning: no animation for view 'still': style 'plain' has no band" in out
    assert spy["trace"] == [] and not (tmp_path / "moving_0.gif").exists()


# -- series -------------------------------------------------------------------------------------
def test_a_scene_over_a_series_renders_one_image_per_snapshot(tmp_path, spy, capsys):
    fields = [swirl(omega=w) for w in (0.5, 1.0, 2.0)]
    for f, t in zip(fields, (10.0, 20.0, 30.0)):
        f.time = t
    save_series(fields, tmp_path / "series.h5")
    path = write_scene(tmp_path, SPEED, f"[views.v]\nsize = {SIZE}\n",
                       field='file = "series.h5"',
                       outputs='[outputs]\nimages = "img/{view}_{snapshot}_t{time:g}.png"\n'
                               'lines = "lines/{snapshot}.h5"\n')
    assert main(["scene", str(path), "--workers", "2", "--out", str(tmp_path / "o")]) == 0
    _, err = capsys.readouterr()
    names = sorted(p.name for p in (tmp_path / "o" / "img").iterdir())
    assert names == ["v_0_t10.png", "v_1_t20.png", "v_2_t30.png"]
    try:
        import flowkit.distributed  # noqa: F401  (the Dask scale-out, when this tree has it)

        assert "trace: 3 snapshots on 2 Dask workers" in err and spy["trace"] == []
    except ImportError:
        assert "run one after the other" in err and len(spy["trace"]) == 3
    assert "[3/3 snapshot 2 t=30] render v:" in err
    # the same pictures as one local trace after the other, without the cache
    seq = run(path, out_dir=tmp_path / "seq", use_cache=False)
    assert [s.action for s in seq.snapshots] == ["trace"] * 3
    for s in seq.snapshots:
        assert s.images["v"].read_bytes() == (tmp_path / "o" / "img" / s.images["v"].name
                                              ).read_bytes()
    # each snapshot's own field: the lines' speed scales with omega
    speeds = [np.median(read_lines(tmp_path / "o" / "lines" / f"{i}.h5").point_data["speed"])
              for i in range(3)]
    assert speeds[0] < speeds[1] < speeds[2]
    images = {(tmp_path / "o" / "img" / n).read_bytes() for n in names}
    assert len(images) == 3
    # --snapshot picks; a pattern without {snapshot} is refused for several snapshots
    assert [s.index for s in run(path, snapshot=-1, out_dir=tmp_path / "o").snapshots] == [2]
    write_scene(tmp_path, SPEED, f"[views.v]\nsize = {SIZE}\n", field='file = "series.h5"',
                outputs='[outputs]\nimages = "one.png"\n')
    with pytest.raises(ValueError, match=r"images = 'one.png' would be overwritten by each of "
                                         r"the 3 snapshots"):
        run(path)


def _chunked_swirls(tmp_path: Path) -> None:
    """s10.h5, s20.h5 (times 10 and 20): swirls at 24^3 nodes in chunks of 8^3, so that 2
    workers own a block each."""
    import h5py

    for i, w in enumerate((0.5, 1.0)):
        f = swirl(omega=w, n=24)
        f.time = 10.0 * (i + 1)
        p = save_field(f, tmp_path / f"s{10 * (i + 1)}.h5")
        with h5py.File(p, "a") as h:
            for name in ("vectors/U", "scalars/T", "scalars/p"):
                a = h[name][...]
                del h[name]
                h.create_dataset(name, data=a, chunks=(8, 8, 8, 3)[:a.ndim])


def test_a_scene_says_how_its_workers_split_the_trace(tmp_path, capsys):
    """``[trace] distribute = "blocks"``: with --workers each snapshot is traced in block mode
    (one snapshot too), the lines and images those of one process; without workers, a note."""
    from flowkit.distributed import blocks
    from flowkit.scene import model

    assert model.DISTRIBUTE == blocks.MODES
    _chunked_swirls(tmp_path)
    views, field = f"[views.v]\nsize = {SIZE}\n", 'series = "s*.h5"'
    outputs = '[outputs]\nimages = "img/{snapshot}.png"\nlines = "lines/{snapshot}.h5"\n'
    path = write_scene(tmp_path, SPEED, views, 'distribute = "blocks"', field, outputs)
    assert load_scene(path).distribute == "blocks"
    seq = run_scene(path, out_dir=tmp_path / "seq", use_cache=False)
    assert seq.notes == [("[trace] distribute = 'blocks' splits a trace across Dask workers "
                          "(--workers N, N > 1); traced in this process")]
    for snap, n in (("all", 2), ("1", 1)):
        out = tmp_path / f"o{n}"
        assert main(["scene", str(path), "--workers", "2", "--snapshot", snap, "--out", str(out),
                     "--no-cache"]) == 0
        s = "s" if n > 1 else ""
        assert (f"trace: {n} snapshot{s} on 2 Dask workers, distribute blocks: asked for"
                in capsys.readouterr().err)
        for i in range(2 - n, 2):
            got = read_lines(out / "lines" / f"{i}.h5")
            assert got.attrs["distribute"] == "blocks" and got.attrs["blocks"] == 2
            assert got.attrs["handoffs_per_line"] > 0
            assert got.equals(read_lines(tmp_path / "seq" / "lines" / f"{i}.h5"))
            assert (out / "img" / f"{i}.png").read_bytes() == \
                (tmp_path / "seq" / "img" / f"{i}.png").read_bytes()
    for bad in ('"domains"', "2"):
        write_scene(tmp_path, SPEED, views, f"distribute = {bad}", field, outputs)
        with pytest.raises(SceneError, match=r"\[trace\]: distribute = .* is not allowed; expected "
                                             r"'auto' or 'seeds' or 'blocks' \(how --workers"):
            load_scene(path)


# -- the demo scene -----------------------------------------------------------------------------
def test_demo_scene_plans_exactly_what_its_styles_read():
    scene = load_scene(ROOT / "examples" / "hotroom_scene.toml")
    plan = make_plan(scene)
    assert plan.attributes == ("speed", "T")  # colour from speed, width from T; halo reads none
    assert [s.index for s in plan.snapshots] == [4] and set(scene.views) == {"overview", "speed"}
    assert scene.style_sources["halo"].endswith("examples/styles/halo.toml")
