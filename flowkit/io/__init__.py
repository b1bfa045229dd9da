"""Lines <-> HDF5 and exports."""
