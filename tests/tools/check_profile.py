#!/usr/bin/env python3
"""Checks a `stipple profile` CSV against laspy + numpy.

Usage: check_profile.py INPUT.las|laz CSV WIDTH x0,y0,x1,y1[,...]

The corridor: points whose horizontal distance to the polyline is at most WIDTH / 2 (segments
with clamped projection, so the ends are round). Compares the number of rows, then every row
(sorted by x, y, z, GPS time): coordinates exactly (the CSV prints shortest round-trip doubles),
distance along the line within 1e-6, and every attribute. Prints one JSON object; exits 1 on any
mismatch.
"""
import json
import sys

import laspy
import numpy as np


def main():
    las = laspy.read(sys.argv[1])
    rows = np.loadtxt(sys.argv[2], delimiter=",", skiprows=1, ndmin=2)
    header = open(sys.argv[2]).readline().strip().split(",")
    width = float(sys.argv[3])
    v = np.array([float(t) for t in sys.argv[4].split(",")]).reshape(-1, 2)
    x, y, z = np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)
    best = np.full(len(x), np.inf)
    along = np.zeros(len(x))
    start = 0.0
    for a, b in zip(v[:-1], v[1:]):
        d = b - a
        l2 = float(d @ d)
        t = np.clip(((x - a[0]) * d[0] + (y - a[1]) * d[1]) / l2, 0.0, 1.0)
        dist = np.hypot(x - (a[0] + t * d[0]), y - (a[1] + t * d[1]))
        better = dist < best
        best = np.where(better, dist, best)
        along = np.where(better, start + t * np.sqrt(l2), along)
        start += np.sqrt(l2)
    keep = best <= width / 2
    problems = []
    if len(rows) != keep.sum():
        problems.append(f"{len(rows)} rows, the reference corridor holds {int(keep.sum())}")
    else:
        col = {name: i for i, name in enumerate(header)}
        ref = np.column_stack([
            along[keep], x[keep], y[keep], z[keep],
            np.asarray(las.intensity)[keep], np.asarray(las.classification)[keep],
            np.asarray(las.return_number)[keep], np.asarray(las.number_of_returns)[keep],
            np.asarray(las.gps_time)[keep], np.asarray(las.point_source_id)[keep],
            np.asarray(las.red)[keep], np.asarray(las.green)[keep], np.asarray(las.blue)[keep]])
        got = rows[:, [col[c] for c in ("distance", "x", "y", "z", "intensity", "classification",
                                         "return_number", "number_of_returns", "gps_time",
                                         "point_source_id", "red", "green", "blue")]]
        order = lambda m: np.lexsort((m[:, 8], m[:, 3], m[:, 2], m[:, 1]))
        ref, got = ref[order(ref)], got[order(got)]
        if not np.array_equal(ref[:, 1:4], got[:, 1:4]):
            problems.append("coordinates differ")
        if np.max(np.abs(ref[:, 0] - got[:, 0]), initial=0) > 1e-6:
            problems.append(f"distance along differs by up to {np.max(np.abs(ref[:, 0] - got[:, 0]))}")
        if not np.array_equal(ref[:, 4:], got[:, 4:]):
            problems.append("attributes differ")
    print(json.dumps({"ok": not problems, "rows": int(len(rows)),
                      "reference": int(keep.sum()), "problems": problems}))
    sys.exit(0 if not problems else 1)


main()
