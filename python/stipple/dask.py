"""Split tiling on a Dask cluster: one task per part (``stipple.tile(..., subset="I/N")``), then
one task merging them (``stipple.merge``). Any ``distributed.Client`` works: a LocalCluster, or
Slurm/PBS through dask-jobqueue (``SLURMCluster``, ``PBSCluster``) or Kubernetes through
dask-kubernetes; the workers need ``stipple`` installed and the inputs and ``out_dir`` on a file
system they share.

A worker that dies mid-task (killed, out of memory, preempted) costs only its part: the
scheduler runs the task again on another worker, and a part's output appears in one rename, so a
re-run replaces what the dead one left (its ``*.partial-*`` directory is removed with the parts
once the merge is done).
"""

from __future__ import annotations

import os
import shutil
import uuid

import stipple


def _tile_part(inputs, part_dir, index, parts, options):
    stipple.tile(inputs, part_dir, subset=f"{index}/{parts}", force=True, **options)
    return part_dir


def _merge(part_dirs, out_dir, force, options):
    return stipple.merge(part_dirs, out_dir, force=force, **options)


def tile(inputs, out_dir, client, parts: int = 4, *, work_dir=None, force: bool = False,
         keep_parts: bool = False, merge_options=None, **options) -> dict:
    """Tiles ``inputs`` into ``out_dir`` on the cluster of ``client`` in ``parts`` parts (a
    power of 4 or 8). ``options`` are :func:`stipple.tile`'s (format, spacing, max_memory,
    threads, progress...), passed to every part. The parts go to a new folder inside
    ``work_dir`` (default ``OUT_DIR.parts``), removed after the merge unless ``keep_parts``
    (``work_dir`` itself only when this call created it). Returns the merge's statistics
    (points, tiles, depth, seconds)."""
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    inputs = [os.path.abspath(os.fspath(p)) for p in inputs]
    out_dir = os.path.abspath(os.fspath(out_dir))
    if os.path.exists(out_dir) and not force:
        raise stipple.Error(f"{out_dir} exists; pass force=True to replace it")
    # The parts go to a folder of this run's own inside `work_dir`: only what this call made is
    # removed afterwards, never the caller's folder or another run's parts.
    base = os.path.abspath(os.fspath(work_dir)) if work_dir else out_dir + ".parts"
    made_base = not os.path.exists(base)
    run = uuid.uuid4().hex[:8]
    work = os.path.join(base, f"stipple-parts-{run}")
    os.makedirs(work)
    futures = [
        client.submit(_tile_part, inputs, os.path.join(work, f"part-{i}"), i, parts, options,
                      key=f"stipple-tile-part-{i}-of-{parts}-{run}", pure=False)
        for i in range(parts)
    ]
    merged = client.submit(_merge, futures, out_dir, force, merge_options or {},
                           key=f"stipple-tile-merge-{run}", pure=False)
    stats = merged.result()
    if not keep_parts:
        shutil.rmtree(work, ignore_errors=True)
        if made_base:
            try:
                os.rmdir(base)
            except OSError:
                pass  # something else was put there meanwhile: left as it is
    return stats
