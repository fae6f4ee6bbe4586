#!/usr/bin/env python3
"""Runs `stipple info`, `render` and `tile` over LAS/LAZ/COPC files with known defects and over
the real files in the data directory (and truncated copies of them), and checks what each does:
it succeeds (exit 0, its output written) or fails cleanly (exit 1, a message naming the file on
stderr, no output left behind: no PNG, no tileset directory); it never crashes (a signal, a
sanitizer report), never hangs (each run is bounded by --timeout seconds).

The defective files are made from valid ones: `stipple generate` writes them (format 3,
LAS 1.4 format 7, LAZ 1.4 format 7) and from the COPC file in the data directory:
wrong header size, point data offset past the end, a point count larger than the file, a VLR whose
length overruns, an EVLR offset inside the point data, a LAZ chunk table offset that points
nowhere, a COPC hierarchy past the end, truncations, and a few more.

  broken_files.py --stipple build/stipple --work /tmp/broken [--data ../shared/data] [--quick]
--quick runs `render` and `tile` only on the generated files (the real ones get `info`), which
keeps the test suite's run short.
"""
import argparse
import os
import shutil
import struct
import subprocess
import sys
import time
from pathlib import Path


def u16(b, o):
    return struct.unpack_from("<H", b, o)[0]


def u32(b, o):
    return struct.unpack_from("<I", b, o)[0]


def u64(b, o):
    return struct.unpack_from("<Q", b, o)[0]


def put(b, fmt, o, v):
    b = bytearray(b)
    struct.pack_into(fmt, b, o, v)
    return bytes(b)


def vlrs(b):
    """(offset of the VLR header, user id, record id, payload length) for every VLR."""
    out, o = [], u16(b, 94)
    for _ in range(u32(b, 100)):
        if o + 54 > len(b):
            break
        out.append((o, b[o + 2 : o + 18].rstrip(b"\0"), u16(b, o + 18), u16(b, o + 20)))
        o += 54 + u16(b, o + 20)
    return out


def defects(las12, las14, laz, copc):
    """name -> bytes of every defective file."""
    d = {}
    size14 = len(las14)
    pts14 = u32(las14, 96)
    # Header size: smaller than any version's, larger than the file, pointing past the VLRs.
    d["header-size-small.las"] = put(las12, "<H", 94, 100)
    d["header-size-huge.las"] = put(las12, "<H", 94, 65535)
    d["header-size-past-points.las"] = put(las14, "<H", 94, min(pts14 + 40, 65535))
    # Point data offset past the end, or inside the header.
    d["offset-past-end.las"] = put(las12, "<I", 96, len(las12) + 1000)
    d["offset-inside-header.las"] = put(las12, "<I", 96, 10)
    # More points than the file holds (legacy and 1.4 counts).
    d["count-too-large.las"] = put(las12, "<I", 107, u32(las12, 107) * 10 + 7)
    d["count14-too-large.las"] = put(las14, "<Q", 247, u64(las14, 247) * 1000 + 1)
    d["count14-huge.las"] = put(las14, "<Q", 247, 2**63 - 1)
    # A VLR whose length runs past the point data / the file; a huge number of VLRs.
    v = vlrs(las14)
    if v:
        d["vlr-overrun.las"] = put(las14, "<H", v[0][0] + 20, 65535)
    d["vlr-count-huge.las"] = put(las14, "<I", 100, 0xFFFFFFFF)
    # EVLRs: an offset inside the point data, past the end, and a huge count.
    d["evlr-inside-points.las"] = put(put(las14, "<Q", 235, pts14 + 10), "<I", 243, 1)
    d["evlr-past-end.las"] = put(put(las14, "<Q", 235, size14 + 1), "<I", 243, 1)
    d["evlr-count-huge.las"] = put(put(las14, "<Q", 235, pts14), "<I", 243, 0xFFFFFFFF)
    # Record format and length.
    d["format-unknown.las"] = put(las12, "<B", 104, 99)
    d["record-length-short.las"] = put(las12, "<H", 105, 4)
    d["record-length-zero.las"] = put(las14, "<H", 105, 0)
    d["scale-zero.las"] = put(las12, "<d", 131, 0.0)
    d["scale-nan.las"] = put(las12, "<d", 131, float("nan"))
    d["bounds-nan.las"] = put(las12, "<d", 179, float("nan"))
    d["version-2.0.las"] = put(las12, "<B", 24, 2)
    # Truncations and tiny files.
    d["truncated-header.las"] = las12[:120]
    d["truncated-points.las"] = las12[: u32(las12, 96) + (len(las12) - u32(las12, 96)) // 2 + 3]
    d["empty.las"] = b""
    d["magic-only.las"] = b"LASF"
    d["not-las.las"] = b"PK\x03\x04" + bytes(400)
    # LAZ: the chunk table offset (8 bytes at the start of the point data) pointing nowhere, to
    # zero, inside the header; point data cut; the LASzip VLR damaged.
    p = u32(laz, 96)
    d["laz-chunk-table-past-end.laz"] = put(laz, "<q", p, len(laz) + 4096)
    d["laz-chunk-table-zero.laz"] = put(laz, "<q", p, 0)
    d["laz-chunk-table-negative.laz"] = put(laz, "<q", p, -1)
    d["laz-chunk-table-in-header.laz"] = put(laz, "<q", p, 16)
    d["laz-truncated.laz"] = laz[: p + (len(laz) - p) // 2]
    d["laz-count-too-large.laz"] = put(laz, "<Q", 247, u64(laz, 247) * 100 + 1)
    for off, user, rec, length in vlrs(laz):
        if user == b"laszip encoded" and rec == 22204:
            d["laz-vlr-chunk-size-zero.laz"] = put(laz, "<I", off + 54 + 12, 0)
            d["laz-vlr-items-huge.laz"] = put(laz, "<H", off + 54 + 32, 0xFFFF)
    if copc:
        for off, user, rec, length in vlrs(copc):
            if user == b"copc" and rec == 1:
                info = off + 54
                d["copc-hierarchy-past-end.copc.laz"] = put(copc, "<Q", info + 40, len(copc) + 64)
                d["copc-hierarchy-size-huge.copc.laz"] = put(copc, "<Q", info + 48, 2**40)
                d["copc-hierarchy-in-header.copc.laz"] = put(copc, "<Q", info + 40, 8)
        d["copc-truncated.copc.laz"] = copc[: len(copc) // 3]
    return d


def run(cmd, timeout):
    start = time.monotonic()
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, errors="replace", timeout=timeout)
        return p.returncode, p.stderr + p.stdout, time.monotonic() - start
    except subprocess.TimeoutExpired:
        return None, "", time.monotonic() - start


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--stipple", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--data", default="")
    ap.add_argument("--timeout", type=float, default=120)
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args()
    work = Path(a.work)
    shutil.rmtree(work, ignore_errors=True)
    (work / "in").mkdir(parents=True)

    def generate(name, fmt, n):
        out = work / "in" / name
        subprocess.run([a.stipple, "generate", "-o", str(out), "-n", str(n), "--point-format",
                        str(fmt), "--threads", "1"], check=True, capture_output=True)
        return out.read_bytes()

    data = Path(a.data) if a.data else None
    # A LAS 1.2 file (format 3) when the data directory has one, else format 3 in LAS 1.4.
    if data and (data / "las" / "1.2-with-color.las").is_file():
        las12 = (data / "las" / "1.2-with-color.las").read_bytes()
        (work / "in" / "valid12.las").write_bytes(las12)
    else:
        las12 = generate("valid12.las", 3, 2000)
    las14 = generate("valid14.las", 7, 3000)
    laz = generate("valid.laz", 7, 60000)
    copc = b""
    if data and (data / "laz" / "lone-star.copc.laz").is_file():
        copc = (data / "laz" / "lone-star.copc.laz").read_bytes()

    files = []  # (path, full check: render and tile too)
    for name, b in sorted(defects(las12, las14, laz, copc).items()):
        f = work / "in" / name
        f.write_bytes(b)
        files.append((f, True))
    for name in ("valid12.las", "valid14.las", "valid.laz"):
        files.append((work / "in" / name, True))
    if data and data.is_dir():
        for f in sorted(list(data.glob("*/*.las")) + list(data.glob("*/*.laz"))):
            files.append((f, not a.quick))
            t = work / "in" / ("cut-" + f.name)
            t.write_bytes(f.read_bytes()[: max(400, f.stat().st_size // 2)])
            files.append((t, not a.quick))

    failures = []
    counts = {"ok": 0, "refused": 0}
    slowest = (0.0, "")
    for f, full in files:
        runs = [("info", [a.stipple, "info", str(f)], None)]
        if full:
            png = work / "out" / (f.name + ".png")
            tiles = work / "out" / (f.name + ".tiles")
            runs.append(("render", [a.stipple, "render", str(f), "-o", str(png), "--width", "64",
                                    "--height", "48"], png))
            runs.append(("tile", [a.stipple, "tile", str(f), "-o", str(tiles), "--threads", "2",
                                  "--max-memory", "256M"], tiles))
        (work / "out").mkdir(exist_ok=True)
        outcome = []
        for what, cmd, output in runs:
            rc, text, secs = run(cmd, a.timeout)
            outcome.append(f"{what} {'timeout' if rc is None else rc} {secs:.1f}s")
            if secs > slowest[0]:
                slowest = (secs, f"{what} {f.name}")
            label = f"{what} {f.name}"
            if rc is None:
                failures.append(f"{label}: still running after {a.timeout:.0f} s")
                continue
            if "Sanitizer" in text or "runtime error:" in text:
                failures.append(f"{label}: sanitizer report\n{text[-3000:]}")
                continue
            if rc == 0:
                counts["ok"] += 1
                if output is not None and not output.exists():
                    failures.append(f"{label}: exit 0 but no {output.name}")
            elif rc == 1:
                counts["refused"] += 1
                if f.name not in text:
                    failures.append(f"{label}: the message does not name the file:\n{text[-600:]}")
                if output is not None and output.exists():
                    failures.append(f"{label}: failed but left {output.name} behind")
            else:
                failures.append(f"{label}: exit {rc} (a crash?)\n{text[-3000:]}")
        print(f"{f.name:40s} " + ", ".join(outcome))
    print(f"{len(files)} files, {counts['ok']} runs succeeded, {counts['refused']} refused "
          f"cleanly; slowest: {slowest[1]} ({slowest[0]:.1f} s)")
    for msg in failures:
        print("FAIL", msg)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
