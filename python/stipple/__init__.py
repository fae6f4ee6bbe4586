"""stipple: LAS/LAZ/COPC point clouds read into numpy, rendered headless on WebGPU and tiled to
3D Tiles, through libstipple (the library the ``stipple`` command line is made of).

Every call that reads, renders or tiles releases the GIL. Errors raise :class:`stipple.Error`
(a ``RuntimeError``) carrying the library's message, which names the file.
"""

from __future__ import annotations

import json
import os
from typing import Optional, Sequence

import numpy as np

from . import _stipple
from ._stipple import Error

__all__ = ["Error", "read", "read_header", "info", "tile", "merge"]


def _path(path) -> str:
    return os.fspath(path)


def read(path, fields: Optional[Sequence[str]] = None) -> np.ndarray:
    """Every point of a LAS, LAZ or COPC file as a numpy structured array.

    Fields are named as laspy names them (``X``, ``Y``, ``Z`` the stored integers,
    ``intensity``, ``return_number``, ``classification``, ``synthetic``, ``scan_angle_rank`` or
    ``scan_angle``, ``gps_time``, ``red``, ``nir``, ``wavepacket_index``... and each extra-bytes
    attribute by its name, scaled to doubles where its descriptor has a scale or offset), plus
    ``x``, ``y``, ``z``: the scaled coordinates as float64. ``fields`` keeps only those named,
    in that order.
    """
    names, formats, offsets, itemsize, data = _stipple.read(
        _path(path), None if fields is None else list(fields)
    )
    dtype = np.dtype(
        {"names": names, "formats": formats, "offsets": offsets, "itemsize": itemsize}
    )
    return data.view(dtype)


def read_header(path) -> dict:
    """The header of a LAS/LAZ/COPC file (no point decoded): version, point_format,
    point_count, scale, offset, min, max, crs, vlrs, extra_bytes... as ``stipple info --json``
    prints it."""
    return json.loads(_stipple.header_json(_path(path)))


def info(path) -> dict:
    """What ``stipple info --json`` says about a file, as a dict."""
    return read_header(path)


def tile(
    inputs,
    out_dir,
    *,
    format: str = "glb",
    crs: str = "",
    spacing: float = 0.0,
    max_memory="2G",
    threads: int = 0,
    force: bool = False,
    max_node_points: int = 60000,
    compress: str = "none",
    implicit: bool = False,
    subtree_levels: int = 6,
    subset: Optional[str] = None,
    progress=None,
) -> dict:
    """LAS/LAZ files -> a 3D Tiles tileset in ``out_dir``, as ``stipple tile`` builds it (same
    options). ``progress(phase, done, total)`` is called as the work advances (an exception it
    raises stops the work and is raised here). ``subset="I/N"`` tiles one part of a split tiling
    (see :func:`merge` and :mod:`stipple.dask`). Returns points, tiles, depth, seconds..."""
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    return _stipple.tile(
        [_path(p) for p in inputs],
        _path(out_dir),
        format,
        crs,
        float(spacing),
        str(max_memory),
        int(threads),
        bool(force),
        int(max_node_points),
        compress,
        bool(implicit),
        int(subtree_levels),
        subset or "",
        progress,
    )


def merge(parts, out_dir, *, force: bool = False, threads: int = 0, max_memory="2G", progress=None) -> dict:
    """The parts of a split tiling (``tile(..., subset="I/N")`` for every I) -> one tileset, as
    ``stipple tile merge`` builds it. The parts are left as they were."""
    return _stipple.merge(
        [_path(p) for p in parts], _path(out_dir), bool(force), int(threads), str(max_memory), progress
    )
