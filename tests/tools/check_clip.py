#!/usr/bin/env python3
"""Checks a `stipple clip` output against laspy (an independent LAS/LAZ reader).

Usage: check_clip.py SPEC.json

SPEC: {"inputs": [...], "output": "...", "boxes": [[minx, miny, minz, maxx, maxy, maxz, yaw_deg?]],
       "polygons": [[[x, y], ...] ring, ...] (one polygon, even-odd), "classes": [..],
       "returns": ["first", ...], "intensity": [a, b], "gps": [a, b], "outside": false}

Selects the points with numpy from laspy's arrays, then compares with the output: the count,
every record byte for byte (both sorted), the header's counts by return and bounds, the CRS and
the VLRs that describe the data. Prints one JSON object; exits 1 on any mismatch.
"""
import json
import math
import sys

import laspy
import numpy as np


def select(las, spec):
    n = len(las.points)
    keep = np.ones(n, dtype=bool)
    cls = np.asarray(las.classification).astype(np.int64)
    rn = np.asarray(las.return_number).astype(np.int64)
    nr = np.asarray(las.number_of_returns).astype(np.int64)
    if "classes" in spec:
        keep &= np.isin(cls, spec["classes"])
    if "returns" in spec:
        kinds = np.zeros(n, dtype=bool)
        for k in spec["returns"]:
            kinds |= {"first": rn <= 1, "last": rn >= nr, "single": nr <= 1,
                      "intermediate": (rn > 1) & (rn < nr)}[k]
        keep &= kinds
    if "intensity" in spec:
        i = np.asarray(las.intensity)
        keep &= (i >= spec["intensity"][0]) & (i <= spec["intensity"][1])
    if "gps" in spec:
        g = np.asarray(las.gps_time)
        keep &= (g >= spec["gps"][0]) & (g <= spec["gps"][1])
    x, y, z = np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)
    region = None
    for b in spec.get("boxes", []):
        cx, cy, cz = (b[0] + b[3]) / 2, (b[1] + b[4]) / 2, (b[2] + b[5]) / 2
        hx, hy, hz = (b[3] - b[0]) / 2, (b[4] - b[1]) / 2, (b[5] - b[2]) / 2
        yaw = math.radians(b[6]) if len(b) > 6 else 0.0
        dx, dy = x - cx, y - cy
        lx = math.cos(yaw) * dx + math.sin(yaw) * dy
        ly = -math.sin(yaw) * dx + math.cos(yaw) * dy
        inside = (np.abs(lx) <= hx) & (np.abs(ly) <= hy) & (np.abs(z - cz) <= hz)
        region = inside if region is None else region | inside
    if "polygons" in spec:
        inside = np.zeros(n, dtype=bool)
        for ring in spec["polygons"]:
            r = ring[:-1] if ring[0] == ring[-1] else ring
            for i in range(len(r)):
                ax, ay = r[i]
                bx, by = r[i - 1]
                crosses = ((ay > y) != (by > y))
                with np.errstate(divide="ignore", invalid="ignore"):
                    xi = (bx - ax) * (y - ay) / (by - ay) + ax
                inside ^= crosses & (x < xi)
        region = inside if region is None else region | inside
    if region is not None:
        keep &= ~region if spec.get("outside") else region
    return keep


def main():
    spec = json.load(open(sys.argv[1]))
    selected = []
    for path in spec["inputs"]:
        las = laspy.read(path)
        selected.append(las.points.array[select(las, spec)])
    source = laspy.read(spec["inputs"][0])
    expected = np.concatenate(selected)
    out = laspy.read(spec["output"])
    problems = []
    got = out.points.array
    if len(got) != len(expected):
        problems.append(f"{len(got)} points written, the reference selects {len(expected)}")
    if out.header.point_count != len(got):
        problems.append(f"header count {out.header.point_count}, file holds {len(got)}")
    if out.header.version.minor != 4:
        problems.append(f"LAS version {out.header.version}, expected 1.4")
    if got.dtype != expected.dtype:
        problems.append("record layout differs from the input's")
    elif len(got) == len(expected):
        order = [f for f in expected.dtype.names][:4]
        if not np.array_equal(np.sort(got, order=order), np.sort(expected, order=order)):
            problems.append("records differ from the input's")
    rn = np.asarray(out.return_number).astype(np.int64)
    by_return = [int((rn == k).sum()) for k in range(1, 16)]
    if list(map(int, out.header.number_of_points_by_return[:15])) != by_return:
        problems.append(f"counts by return {list(out.header.number_of_points_by_return)} "
                        f"but the points give {by_return}")
    if len(got):
        for axis, values, lo, hi in (("x", out.x, out.header.mins[0], out.header.maxs[0]),
                                     ("y", out.y, out.header.mins[1], out.header.maxs[1]),
                                     ("z", out.z, out.header.mins[2], out.header.maxs[2])):
            if abs(float(np.min(values)) - lo) > 1e-9 or abs(float(np.max(values)) - hi) > 1e-9:
                problems.append(f"bounds {axis} {lo}..{hi}, points span "
                                f"{float(np.min(values))}..{float(np.max(values))}")
    src_crs, out_crs = source.header.parse_crs(), out.header.parse_crs()
    if (src_crs is None) != (out_crs is None) or (src_crs is not None and src_crs != out_crs):
        problems.append(f"CRS {out_crs} differs from the input's {src_crs}")
    data_vlrs = lambda h: sorted((v.user_id, v.record_id) for v in h.vlrs
                                 if v.user_id not in ("laszip encoded", "copc", "lascompatible"))
    if data_vlrs(out.header) != data_vlrs(source.header):
        problems.append(f"VLRs {data_vlrs(out.header)}, input has {data_vlrs(source.header)}")
    data_evlrs = lambda h: sorted((v.user_id, v.record_id, bytes(v.record_data_bytes()))
                                  for v in (h.evlrs or []) if v.user_id != "copc")
    if data_evlrs(out.header) != data_evlrs(source.header):
        problems.append(f"EVLRs differ: {[e[:2] for e in data_evlrs(out.header)]}, input has "
                        f"{[e[:2] for e in data_evlrs(source.header)]}")
    print(json.dumps({"ok": not problems, "written": int(len(got)),
                      "reference": int(len(expected)), "problems": problems}))
    sys.exit(0 if not problems else 1)


main()
