"""Options every command that reads a field takes for unstructured meshes (.vtu, .vtm)."""

from __future__ import annotations

RESAMPLE_HELP = ("unstructured meshes (.vtu, .vtm): the grid they are resampled onto, NX,NY,NZ "
                 "or spacing:DX (default: a lattice of nodes is kept as it is, anything else "
                 "gets a grid as fine as the mesh's fine cells, under a node cap)")


def add_mesh_options(p) -> None:
    p.add_argument("--resample", metavar="NX,NY,NZ|spacing:DX", help=RESAMPLE_HELP)
    p.add_argument("--block", help=".vtm multiblock files: the block to read (default internal)")
    p.add_argument("--data", choices=["point", "cell"],
                   help="VTK files (.vti .vtr .vtu .vtm): point data (default) or cell data (on "
                        "a mesh each node takes the value of its cell, constant in the cell)")


def mesh_options(args) -> dict:
    """The mesh options given on the command line, as load_field keywords."""
    return {k: v for k in ("resample", "block", "data")
            if (v := getattr(args, k, None)) is not None}
