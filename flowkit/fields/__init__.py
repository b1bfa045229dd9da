"""Grids, fields, readers and analytic fields."""

from .field import Field, FieldError
from .grid import Grid, GridError

__all__ = ["Field", "FieldError", "Grid", "GridError"]
