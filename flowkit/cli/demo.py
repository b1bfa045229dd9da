"""``flowkit demo``: the main job on the built-in demo data (the OpenFOAM heated room).

For now it loads the room and prints its summary; tracing and rendering steps extend ``demo``.
"""

from __future__ import annotations


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "demo", help="run the main job on the built-in heated-room data", description=__doc__
    )
    p.add_argument(
        "--snapshot",
        type=int,
        default=-1,
        help="heated-room snapshot position (default -1: the last, t = 2000 s)",
    )
    p.set_defaults(func=run)


def run(args) -> int:
    field = demo(snapshot=args.snapshot)
    print(field.summary())
    return 0


def demo(snapshot: int = -1):
    """Load the built-in heated room; later steps (trace, render) build on the Field returned."""
    from ..datasets import hotroom

    return hotroom(snapshot=snapshot)
