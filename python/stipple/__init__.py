"""stipple: LAS/LAZ/COPC point clouds and Gaussian splat files read into numpy, rendered
headless on WebGPU and tiled to 3D Tiles, through libstipple (the library the ``stipple``
command line is made of).

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

__all__ = ["Error", "read", "read_header", "info", "render", "tile", "merge"]


def _path(path) -> str:
    return os.fspath(path)


def read(path, fields: Optional[Sequence[str]] = None):
    """Every point of a LAS, LAZ or COPC file as a numpy structured array; or the splats of a
    3D Gaussian splat file (INRIA or compressed PLY, SPZ, .splat, .ksplat, SOG) as a dict.

    Splats: ``positions`` (N, 3), ``scales`` (N, 3, linear), ``rotations`` (N, 4, unit
    quaternions x, y, z, w), ``opacities`` (N, linear), ``sh_dc`` (N, 3: colour is
    0.5 + 0.28209479 * sh_dc) and ``sh_rest`` (N, (degree+1)^2 - 1, 3: coefficient-major), all
    float32, with ``sh_degree``, ``format`` and ``transform`` (4x4 rows, to the source's frame).

    Fields are named as laspy names them (``X``, ``Y``, ``Z`` the stored integers,
    ``intensity``, ``return_number``, ``classification``, ``synthetic``, ``scan_angle_rank`` or
    ``scan_angle``, ``gps_time``, ``red``, ``nir``, ``wavepacket_index``... and each extra-bytes
    attribute by its name, scaled to doubles where its descriptor has a scale or offset), plus
    ``x``, ``y``, ``z``: the scaled coordinates as float64. ``fields`` keeps only those named,
    in that order.
    """
    if _stipple.is_splat_path(_path(path)):
        if fields is not None:
            raise Error(f"{_path(path)}: fields select LAS dimensions; a splat file has none")
        return _stipple.read_splats(_path(path))
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


_COLUMNS = {
    "x": np.float64,
    "y": np.float64,
    "z": np.float64,
    "intensity": np.uint16,
    "red": np.uint16,
    "green": np.uint16,
    "blue": np.uint16,
    "classification": np.uint8,
    "return_number": np.uint8,
    "number_of_returns": np.uint8,
}


def _columns(points) -> dict:
    """Points as contiguous columns of the types the library reads: a structured array (as
    :func:`read` returns: ``x``, ``y``, ``z`` and the optional attributes by their laspy names)
    or an (N, 3) float array of x, y, z. Columns already of the right type and layout are
    passed without a copy."""
    points = np.asarray(points)
    if points.dtype.names is None:
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(
                f"points: expected a structured array with x, y, z or an (N, 3) array, "
                f"got shape {points.shape}"
            )
        xyz = np.asarray(points, dtype=np.float64)
        if xyz.strides[0] % 8 or xyz.strides[1] % 8:
            xyz = np.ascontiguousarray(xyz)
        return {name: xyz[:, i] for i, name in enumerate("xyz")}
    missing = [n for n in "xyz" if n not in points.dtype.names]
    if missing:
        raise ValueError(
            f"points: no field {', '.join(missing)} (fields: {', '.join(points.dtype.names)})"
        )
    columns = {}
    for name, dtype in _COLUMNS.items():
        if name in points.dtype.names:
            column = points[name]
            if (
                column.dtype != dtype
                or column.strides[0] % column.itemsize
                or column.ctypes.data % column.itemsize
            ):
                column = np.ascontiguousarray(column, dtype=dtype)
            columns[name] = column
    return columns


def _camera(camera) -> str:
    if camera is None:
        return ""
    if isinstance(camera, str):
        return camera
    values = np.asarray(camera, dtype=np.float64).ravel()
    if values.size != 6:
        raise ValueError("camera: expected (eye, target) or 6 numbers eye_x..target_z")
    return ",".join(repr(float(v)) for v in values)


def _seq(values, n, what):
    if values is None:
        return None
    values = [float(v) for v in values]
    if len(values) != n:
        raise ValueError(f"{what}: expected {n} numbers, got {len(values)}")
    return values


def render(
    points,
    width: int = 1280,
    height: int = 720,
    *,
    camera=None,
    azimuth: float = 30.0,
    elevation: float = 40.0,
    fov: float = 50.0,
    color: str = "auto",
    renderer: str = "auto",
    point_size: float = 0.0,
    point_size_mode: str = "fixed",
    background=None,
    constant_color=None,
    elevation_range=None,
    intensity_range=None,
    edl: bool = True,
    splat: str = "blend",
    hqs: bool = False,
    clod_k: float = 0.0,
    max_sse: float = 0.0,
    memory_mb: int = 512,
    budget: int = 0,
    backend: str = "",
    frames: int = 1,
) -> np.ndarray:
    """Renders points headless (WebGPU) to an (height, width, 4) uint8 RGBA array, through the
    pipeline and options of ``stipple render`` (which writes the same pixels as PNG).

    ``points`` is a path (LAS/LAZ/COPC, a 3D Tiles tileset.json, Potree or EPT metadata), a
    list of LAS/LAZ paths, a structured array as :func:`read` returns (``x``, ``y``, ``z``;
    ``red``/``green``/``blue``, ``intensity``, ``classification``, ``return_number``,
    ``number_of_returns`` when present) or an (N, 3) array of x, y, z. ``camera`` is
    ``(eye, target)`` or 6 numbers in the data's coordinates (Z up), or None to frame the data
    from ``azimuth``/``elevation`` (degrees). ``color`` is auto, rgb, intensity, classification,
    elevation, return or constant; ``renderer`` auto, billboard or compute; ``point_size`` 0
    sizes points from the data's density; ``background`` and ``constant_color`` are r, g, b in
    0..1. The other options are those of ``stipple render``.
    """
    inputs, columns = [], None
    if isinstance(points, (str, os.PathLike)):
        inputs = [_path(points)]
    elif isinstance(points, (list, tuple)) and points and all(
        isinstance(p, (str, os.PathLike)) for p in points
    ):
        inputs = [_path(p) for p in points]
    else:
        columns = _columns(points)
    return _stipple.render(
        inputs,
        columns,
        int(width),
        int(height),
        _camera(camera),
        float(azimuth),
        float(elevation),
        float(fov),
        str(color),
        str(renderer),
        float(point_size),
        str(point_size_mode),
        _seq(background, 3, "background"),
        _seq(constant_color, 3, "constant_color"),
        _seq(elevation_range, 2, "elevation_range"),
        _seq(intensity_range, 2, "intensity_range"),
        bool(edl),
        str(splat),
        bool(hqs),
        float(clod_k),
        float(max_sse),
        int(memory_mb),
        int(budget),
        str(backend),
        int(frames),
    )


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
