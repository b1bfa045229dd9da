"""``flowkit demo``: the main job on the built-in demo data (the OpenFOAM heated room).

Prints the room's summary, then runs the demo scene (examples/hotroom_scene.toml: trace, lines
file, two styled views) with its outputs and its lines cache in ``--out`` (default ``out/``).
"""

from __future__ import annotations

from pathlib import Path

from ..datasets import bundled


def scene_path() -> Path:
    """examples/hotroom_scene.toml (the style it references travels with it in a wheel)."""
    return bundled("examples/hotroom_scene.toml", "the demo scene is not here; flowkit demo "
                   "runs from a source checkout or an installed wheel")


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "demo", help="run the demo scene on the built-in heated-room data", description=__doc__
    )
    p.add_argument(
        "--snapshot",
        default="-1",
        help="heated-room snapshot position, positions a,b,c or 'all' (default -1: the last, "
             "t = 2000 s)",
    )
    p.add_argument("--out", default="out", help="directory for the outputs (default: out/)")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..scene import run_scene
    from .scene import snapshot_arg

    snap = snapshot_arg(args.snapshot)
    field = demo(snapshot=snap if isinstance(snap, int) else -1)
    print(field.summary())
    out = Path(args.out)
    res = run_scene(scene_path(), snapshot=snap, out_dir=out, cache_dir=out / ".flowkit-cache")
    for r in res.snapshots:
        for path in ([r.lines_path] if r.lines_path else []) + list(r.images.values()):
            print(f"wrote {path}")
    return 0


def demo(snapshot: int = -1):
    """Load the built-in heated room (the Field the demo scene traces)."""
    from ..datasets import hotroom

    return hotroom(snapshot=snapshot)
