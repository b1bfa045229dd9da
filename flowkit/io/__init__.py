"""Lines <-> HDF5 (CF trajectories + VTKHDF in one file) and atomic outputs."""

from .atomic import AtomicPath, atomic_path
from .lines_h5 import LinesFileError, LinesWriter, is_lines_file, read_lines, write_lines

__all__ = ["AtomicPath", "LinesFileError", "LinesWriter", "atomic_path", "is_lines_file",
           "read_lines", "write_lines"]
