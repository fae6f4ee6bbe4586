"""Split tiling on Dask worker processes vs one process (bench/RESULTS.md).

    .deps/python/bin/python bench/split_tiling.py INPUT.laz [--parts 4] [--workers 2]

Runs stipple.tile in this process with one thread per worker (--workers threads), then
stipple.dask.tile with --parts parts on a LocalCluster of --workers single-threaded worker
processes (cluster start-up timed apart), and prints both wall times and the tilesets' point
counts (stipple info).
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import stipple
import stipple.dask


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("input")
    ap.add_argument("--parts", type=int, default=4)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--max-memory", default="2G")
    ap.add_argument("--stipple", default=os.path.join(os.path.dirname(__file__), "..", "build", "stipple"))
    a = ap.parse_args()
    from distributed import Client, LocalCluster

    with tempfile.TemporaryDirectory(dir=os.path.dirname(os.path.abspath(a.input))) as tmp:
        t = time.perf_counter()
        one = stipple.tile(a.input, os.path.join(tmp, "one"), threads=a.workers, max_memory=a.max_memory)
        t_one = time.perf_counter() - t
        t = time.perf_counter()
        with LocalCluster(n_workers=a.workers, threads_per_worker=1, processes=True,
                          dashboard_address=None, silence_logs=50) as cluster, Client(cluster) as client:
            t_start = time.perf_counter() - t
            t = time.perf_counter()
            split = stipple.dask.tile([a.input], os.path.join(tmp, "split"), client, parts=a.parts,
                                      threads=1, max_memory=a.max_memory)
            t_split = time.perf_counter() - t
        counts = []
        for name in ("one", "split"):
            out = subprocess.run([a.stipple, "info", os.path.join(tmp, name, "tileset.json"), "--json"],
                                 check=True, capture_output=True, text=True).stdout
            counts.append(json.loads(out)["points"])
    print(f"input {a.input}: {one['points']} points")
    print(f"one process, {a.workers} threads: {t_one:.2f} s ({one['tiles']} tiles, {counts[0]} points)")
    print(f"dask, {a.parts} parts on {a.workers} worker processes x 1 thread: {t_split:.2f} s "
          f"({split['tiles']} tiles, {counts[1]} points; cluster start {t_start:.2f} s)")


if __name__ == "__main__":
    sys.exit(main())
