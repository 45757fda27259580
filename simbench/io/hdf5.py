"""Opening HDF5 files with errors that name the file."""

from __future__ import annotations

import os

import h5py

from simbench.errors import InputError


def open_hdf5(path: str | os.PathLike[str]) -> h5py.File:
    """Open an HDF5 file for reading, with errors that say what is wrong with which file."""
    if os.path.isdir(path):
        raise InputError(f"{path}: expected a file, got a directory")
    try:
        return h5py.File(path, "r")
    except FileNotFoundError:
        raise InputError(f"{path}: cannot read: no such file") from None
    except OSError as exc:
        raise InputError(f"{path}: not an HDF5 file ({exc})") from None
