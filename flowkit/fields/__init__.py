"""Grids, fields, readers and analytic fields."""

from .field import Field, FieldError
from .grid import Grid, GridError
from .readers import ReaderError, load_field, load_series
from .writers import save_field, save_series

__all__ = [
    "Field", "FieldError", "Grid", "GridError", "ReaderError",
    "load_field", "load_series", "save_field", "save_series",
]  # fmt: skip
