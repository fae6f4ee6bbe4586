#!/usr/bin/env python3
"""Writes a COPC 1.0 file from a LAS 1.4 file (point format 6-8) for the tests: an octree of
`--depth` levels, at most `--capacity` points a node above the deepest level (the first points
of a seeded shuffle, so every level is a uniform subsample), one LAZ chunk a node (lazrs, variable
chunk sizes, with its chunk table), and the hierarchy split into pages: one at the root and one
at every node of the levels in `--page-depths`, referenced from the page above by an entry with
point count -1.

`--corrupt KIND` damages the hierarchy the way the reader must survive: `offset` (a node's chunk
past the end of the file), `cycle` (a child page pointing back at the root page), `orphan` (a
node whose parent is absent), `pagesize` (a child page size that is not a multiple of 32),
`depth` (a key deeper than COPC allows).
"""
import argparse
import struct

import laspy
import lazrs
import numpy as np


def vlr_header(user, record, length, description=b""):
    return struct.pack("<H16sHH32s", 0, user, record, length, description)


def evlr_header(user, record, length, description=b""):
    return struct.pack("<H16sHQ32s", 0, user, record, length, description)


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("input")
    ap.add_argument("output")
    ap.add_argument("--depth", type=int, default=6, help="deepest octree level")
    ap.add_argument("--capacity", type=int, default=4000, help="points a node above the deepest")
    ap.add_argument("--page-depths", default="2,4", help="levels whose nodes start a page")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--corrupt", default="")
    a = ap.parse_args()

    las = laspy.read(a.input)
    if las.header.point_format.id not in (6, 7, 8):
        las = laspy.convert(las, point_format_id=7, file_version="1.4")
    fmt_id = las.header.point_format.id
    records = las.points.array
    n = len(records)
    xyz = np.stack([np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)], axis=1)
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    center = (lo + hi) / 2
    half = float((hi - lo).max() / 2 * 1.0001 + 1e-6)
    cmin = center - half

    rng = np.random.default_rng(a.seed)
    remaining = rng.permutation(n)
    nodes = {}  # (d, x, y, z) -> indices
    for d in range(a.depth + 1):
        if len(remaining) == 0:
            break
        side = 2 * half / (1 << d)
        cells = np.clip(((xyz[remaining] - cmin) / side).astype(np.int64), 0, (1 << d) - 1)
        ids = (cells[:, 0] << 42) | (cells[:, 1] << 21) | cells[:, 2]
        order = np.argsort(ids, kind="stable")
        sids = ids[order]
        starts = np.r_[0, np.flatnonzero(np.diff(sids)) + 1]
        rank = np.arange(len(sids)) - np.repeat(starts, np.diff(np.r_[starts, len(sids)]))
        take = np.ones(len(sids), bool) if d == a.depth else rank < a.capacity
        chosen = remaining[order[take]]
        chosen_ids = sids[take]
        bounds = np.r_[0, np.flatnonzero(np.diff(chosen_ids)) + 1, len(chosen_ids)]
        for s, e in zip(bounds[:-1], bounds[1:]):
            i = int(chosen_ids[s])
            nodes[(d, i >> 42, (i >> 21) & ((1 << 21) - 1), i & ((1 << 21) - 1))] = chosen[s:e]
        remaining = remaining[order[~take]]
    keys = sorted(nodes)

    vlr = lazrs.LazVlr.new_for_compression(fmt_id, records.dtype.itemsize - {6: 30, 7: 36, 8: 38}[fmt_id], True)
    laz_record = vlr.record_data()
    header_size, info_size = 375, 160
    offset_to_points = header_size + 54 + info_size + 54 + len(laz_record)

    out = open(a.output, "w+b")
    out.write(b"\0" * offset_to_points)
    comp = lazrs.LasZipCompressor(out, vlr)
    comp.reserve_offset_to_chunk_table()  # the 8-byte pointer before the first chunk
    chunks = {}
    for k in keys:
        start = out.tell()
        comp.compress_many(records[nodes[k]].tobytes())
        comp.finish_current_chunk()
        chunks[k] = (start, out.tell() - start, len(nodes[k]))
    comp.done()
    out.seek(0, 2)
    evlr_start = out.tell()

    page_depths = sorted(int(x) for x in a.page_depths.split(",") if x)

    def page_root(k):
        """The key whose page lists k: the deepest page level <= k's depth, or the root."""
        for pd in reversed(page_depths):
            if pd <= k[0]:
                s = k[0] - pd
                return (pd, k[1] >> s, k[2] >> s, k[3] >> s)
        return (0, 0, 0, 0)

    pages = {(0, 0, 0, 0): []}
    for k in keys:
        r = page_root(k)
        pages.setdefault(r, []).append(("node", k))
    # Page roots deeper than the root are referenced from the page above them.
    for r in sorted(pages, key=lambda k: -k[0]):
        if r == (0, 0, 0, 0):
            continue
        parent_key = (r[0] - 1, r[1] >> 1, r[2] >> 1, r[3] >> 1)
        pages.setdefault(page_root(parent_key), []).append(("page", r))
    order = sorted(pages, key=lambda k: (k[0], k))
    sizes = {r: 32 * len(pages[r]) for r in order}
    offsets, at = {}, evlr_start + 60
    for r in order:
        offsets[r] = at
        at += sizes[r]
    blob = b""
    first_child_page = next((r for r in order if r != (0, 0, 0, 0)), None)
    for r in order:
        for kind, k in pages[r]:
            if kind == "node":
                off, size, count = chunks[k]
                if a.corrupt == "offset" and k == keys[-1]:
                    off = at + 10_000
                if a.corrupt == "depth" and k == keys[-1]:
                    k = (40, 0, 0, 0)
                if a.corrupt == "orphan" and k == keys[-1]:
                    k = (k[0] + 2, k[1] * 4, k[2] * 4, k[3] * 4)
                blob += struct.pack("<iiiiQii", *k, off, size, count)
            else:
                off, size = offsets[k], sizes[k]
                if a.corrupt == "cycle" and k == first_child_page:
                    off, size = offsets[(0, 0, 0, 0)], sizes[(0, 0, 0, 0)]
                if a.corrupt == "pagesize" and k == first_child_page:
                    size -= 7
                blob += struct.pack("<iiiiQii", *k, off, size, -1)
    out.write(evlr_header(b"copc", 1000, len(blob), b"EPT hierarchy"))
    out.write(blob)

    spacing = 2 * half / 64
    info = struct.pack("<5d2Q2d11Q", *center, half, spacing, offsets[(0, 0, 0, 0)],
                       sizes[(0, 0, 0, 0)], 0.0, 0.0, *([0] * 11))
    h = las.header
    by_return = np.bincount(np.clip(np.asarray(las.return_number), 0, 15), minlength=16)[1:16]
    head = struct.pack(
        "<4sHH16sBB32s32sHHHIIBHI5I3d3d6dQQIQ15Q", b"LASF", 0, 0x10, b"\0" * 16, 1, 4,
        b"stipple tests", b"write_copc.py", 1, 2026, header_size, offset_to_points, 2,
        fmt_id | 0x80, records.dtype.itemsize, 0, 0, 0, 0, 0, 0, *h.scales, *h.offsets,
        hi[0], lo[0], hi[1], lo[1], hi[2], lo[2], 0, evlr_start, 1, n, *[int(x) for x in by_return])
    assert len(head) == header_size, len(head)
    out.seek(0)
    out.write(head)
    out.write(vlr_header(b"copc", 1, info_size, b"COPC info"))
    out.write(info)
    out.write(vlr_header(b"laszip encoded", 22204, len(laz_record), b"lazrs"))
    out.write(laz_record)
    out.close()
    levels = {}
    for k in keys:
        levels[k[0]] = levels.get(k[0], 0) + 1
    print(f"{a.output}: {n} points, {len(keys)} nodes, {len(pages)} pages, levels {levels}")


if __name__ == "__main__":
    main()
