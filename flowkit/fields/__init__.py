"""Grids, fields, readers and analytic fields."""

from .field import Field, FieldError
from .grid import Grid, GridError
from .readers import ReaderError, load_field, load_series
from .writers import save_field, save_series


def from_pyvista(grid, vector=None, source="<pyvista>"):
    """A Field from a ``pyvista.ImageData`` or ``RectilinearGrid`` (``io/pyvista_io.py``)."""
    from ..io.pyvista_io import field_from_pyvista

    return field_from_pyvista(grid, vector, source)

__all__ = [
    "Field", "FieldError", "Grid", "GridError", "ReaderError",
    "from_pyvista", "load_field", "load_series", "save_field", "save_series",
]  # fmt: skip
