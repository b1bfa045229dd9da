"""``flowkit scene scene.toml [--explain] [--snapshot N|all] [--workers N] [--out DIR]``

Runs a scene file: loads each snapshot, traces (or reuses cached lines), writes the lines file
and one PNG per view, reporting each stage.  ``--explain`` prints what would be computed and why
(which style reads which attribute, what the cache holds) and runs nothing.
"""

from __future__ import annotations

from . import CLIError


def snapshot_arg(text: str):
    """'all', a position, or positions separated by commas."""
    if text == "all":
        return "all"
    try:
        vals = [int(v) for v in text.split(",")]
    except ValueError:
        raise CLIError(f"--snapshot {text!r}: expected 'all', a position (e.g. -1) or "
                       "positions separated by commas") from None
    return vals[0] if len(vals) == 1 else vals


def register(subparsers) -> None:
    p = subparsers.add_parser("scene", help="run a scene file: field -> lines -> images",
                              description=__doc__)
    p.add_argument("scene", help="TOML scene file (see examples/hotroom_scene.toml)")
    p.add_argument("--explain", action="store_true",
                   help="print what will be computed and why, then stop")
    p.add_argument("--snapshot", help="'all', a position or positions a,b,c (default: the "
                   "scene's [field] snapshot)")
    p.add_argument("--workers", type=int, help="run snapshots on N Dask workers")
    p.add_argument("--out", help="directory for the outputs (default: the scene file's)")
    p.add_argument("--cache-dir", help="cache directory (default: the scene's [cache] dir)")
    p.add_argument("--no-cache", action="store_true", help="neither read nor write the cache")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..scene import LinesCache, load_scene, make_plan, run_scene

    if args.workers is not None and args.workers < 1:
        raise CLIError(f"--workers {args.workers}: expected a positive integer")
    snap = snapshot_arg(args.snapshot) if args.snapshot is not None else None
    scene = load_scene(args.scene)
    if args.explain:
        plan = make_plan(scene, snap)
        cache = None
        if scene.cache_enabled and not args.no_cache:
            cache = LinesCache(args.cache_dir or scene.cache_dir)
        print(plan.explain(cache))
        return 0
    res = run_scene(scene, snapshot=snap, out_dir=args.out, cache_dir=args.cache_dir,
                    use_cache=False if args.no_cache else None, workers=args.workers)
    for r in res.snapshots:
        anims = [p for paths in r.animations.values() for p in paths]
        for path in ([r.lines_path] if r.lines_path else []) + list(r.images.values()) + anims:
            print(f"wrote {path}")
    return 0
