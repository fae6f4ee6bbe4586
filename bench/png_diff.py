#!/usr/bin/env python3
"""bench/png_diff.py A.png B.png [--threshold N]: how far two images of the same size are apart,
with the standard library only (the GPU machine has no imaging packages): 8-bit RGB or RGBA PNGs,
non-interlaced, as `stipple render` and a browser's canvas.toBlob write them. Prints one JSON line:
the mean absolute difference over the RGB channels (of 255), the largest, and the fraction of
pixels whose largest channel difference exceeds --threshold (default 16)."""
import argparse, json, struct, sys, zlib


def read_png(path):
    data = open(path, 'rb').read()
    if data[:8] != b'\x89PNG\r\n\x1a\n':
        sys.exit(f'{path}: not a PNG')
    pos, idat, width = 8, [], None
    while pos + 8 <= len(data):
        n, kind = struct.unpack('>I4s', data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        pos += 12 + n
        if kind == b'IHDR':
            width, height, depth, ctype, _, _, interlace = struct.unpack('>IIBBBBB', body)
            if depth != 8 or ctype not in (2, 6) or interlace:
                sys.exit(f'{path}: only 8-bit RGB/RGBA non-interlaced PNGs (depth {depth}, type {ctype})')
        elif kind == b'IDAT':
            idat.append(body)
        elif kind == b'IEND':
            break
    if width is None:
        sys.exit(f'{path}: no IHDR')
    bpp = 3 if ctype == 2 else 4
    raw = zlib.decompress(b''.join(idat))
    stride = width * bpp
    out = bytearray(stride * height)
    prev = bytearray(stride)
    for y in range(height):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        if f == 1:
            for i in range(bpp, stride):
                line[i] = (line[i] + line[i - bpp]) & 255
        elif f == 2:
            line = bytearray((a + b) & 255 for a, b in zip(line, prev))
        elif f == 3:
            for i in range(stride):
                left = line[i - bpp] if i >= bpp else 0
                line[i] = (line[i] + ((left + prev[i]) >> 1)) & 255
        elif f == 4:
            for i in range(stride):
                a = line[i - bpp] if i >= bpp else 0
                b = prev[i]
                c = prev[i - bpp] if i >= bpp else 0
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        elif f != 0:
            sys.exit(f'{path}: bad filter {f} on row {y}')
        out[y * stride:(y + 1) * stride] = line
        prev = line
    return width, height, bpp, out


p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
p.add_argument('a')
p.add_argument('b')
p.add_argument('--threshold', type=int, default=16)
args = p.parse_args()
wa, ha, ba, pa = read_png(args.a)
wb, hb, bb, pb = read_png(args.b)
if (wa, ha) != (wb, hb):
    sys.exit(f'sizes differ: {wa}x{ha} against {wb}x{hb}')
total = worst = over = 0
for i in range(wa * ha):
    d = max(abs(pa[i * ba + c] - pb[i * bb + c]) for c in range(3))
    total += sum(abs(pa[i * ba + c] - pb[i * bb + c]) for c in range(3))
    worst = max(worst, d)
    over += d > args.threshold
print(json.dumps({'a': args.a, 'b': args.b, 'size': f'{wa}x{ha}', 'mean_abs': round(total / (3 * wa * ha), 4),
                  'max': worst, 'over_threshold': round(over / (wa * ha), 6), 'threshold': args.threshold}))
