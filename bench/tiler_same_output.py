#!/usr/bin/env python3
"""Compares two `stipple tile` outputs (glb, no compression): the same files, tileset.json and
subtrees byte for byte, and every tile the same set of points (every vertex attribute of the
primitive, as bytes; the order of points inside a tile is free, since the distribution appends
batches in the order the threads finish them).

usage: tiler_same_output.py DIR_A DIR_B    exit 0 when the same, 1 with the differences listed
"""
import json
import os
import struct
import sys

SIZES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
COMPS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


def glb_points(path):
    data = open(path, "rb").read()
    magic, _, length = struct.unpack_from("<III", data, 0)
    if magic != 0x46546C67 or length != len(data):
        raise ValueError(f"{path}: not a glb")
    at, doc, binary = 12, None, b""
    while at < length:
        clen, ctype = struct.unpack_from("<II", data, at)
        chunk = data[at + 8:at + 8 + clen]
        if ctype == 0x4E4F534A:
            doc = json.loads(chunk)
        elif ctype == 0x004E4942:
            binary = chunk
        at += 8 + clen
    columns = []
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            if "extensions" in prim and "KHR_draco_mesh_compression" in prim["extensions"]:
                raise ValueError(f"{path}: compressed")
            for name in sorted(prim["attributes"]):
                acc = doc["accessors"][prim["attributes"][name]]
                view = doc["bufferViews"][acc["bufferView"]]
                if "extensions" in view:
                    raise ValueError(f"{path}: compressed buffer view")
                size = SIZES[acc["componentType"]] * COMPS[acc["type"]]
                stride = view.get("byteStride", size)
                base = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
                columns.append([binary[base + i * stride:base + i * stride + size]
                                for i in range(acc["count"])])
    return sorted(b"".join(p) for p in zip(*columns))


def files(root):
    out = set()
    for d, _, names in os.walk(root):
        for n in names:
            out.add(os.path.relpath(os.path.join(d, n), root))
    return out


def main():
    a, b = sys.argv[1], sys.argv[2]
    fa, fb = files(a), files(b)
    problems = [f"only in {a}: {f}" for f in sorted(fa - fb)]
    problems += [f"only in {b}: {f}" for f in sorted(fb - fa)]
    tiles = 0
    for f in sorted(fa & fb):
        pa, pb = os.path.join(a, f), os.path.join(b, f)
        if f.endswith(".glb"):
            tiles += 1
            if glb_points(pa) != glb_points(pb):
                problems.append(f"{f}: the points differ")
        elif open(pa, "rb").read() != open(pb, "rb").read():
            problems.append(f"{f}: differs")
    for p in problems:
        print(p)
    print(f"{len(fa & fb)} files, {tiles} tiles compared: "
          f"{'the same' if not problems else f'{len(problems)} differences'}")
    sys.exit(1 if problems else 0)


main()
