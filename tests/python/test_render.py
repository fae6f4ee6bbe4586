"""stipple.render against `stipple render`: the same points and camera give the same pixels."""

import struct
import subprocess
import zlib

import laspy
import numpy as np
import pytest

import stipple


def read_png(path):
    """An 8-bit RGB or RGBA PNG (as stipple writes them) as an (H, W, 4) uint8 array."""
    raw = path.read_bytes()
    assert raw[:8] == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG"
    pos, idat, header = 8, b"", None
    while pos < len(raw):
        (length,) = struct.unpack(">I", raw[pos : pos + 4])
        kind, body = raw[pos + 4 : pos + 8], raw[pos + 8 : pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
    width, height, depth, color, _, _, interlace = header
    assert depth == 8 and color in (2, 6) and interlace == 0, header
    bpp = 4 if color == 6 else 3
    stride = width * bpp
    data = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(height, stride + 1)
    out = np.zeros((height, stride), np.int32)
    prev = np.zeros(stride, np.int32)
    for y in range(height):
        kind, line = data[y, 0], data[y, 1:].astype(np.int32)
        if kind == 0:
            row = line
        elif kind == 2:
            row = (line + prev) & 255
        else:  # Sub, Average, Paeth depend on the pixel to the left: byte by byte
            row = np.zeros(stride, np.int32)
            for x in range(stride):
                a = row[x - bpp] if x >= bpp else 0
                b, c = prev[x], (prev[x - bpp] if x >= bpp else 0)
                if kind == 1:
                    p = a
                elif kind == 3:
                    p = (a + b) // 2
                else:
                    pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
                    p = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                row[x] = (line[x] + p) & 255
        out[y], prev = row, row
    image = out.astype(np.uint8).reshape(height, width, bpp)
    if bpp == 3:
        image = np.concatenate([image, np.full((height, width, 1), 255, np.uint8)], axis=2)
    return image


def cli_render(stipple_cli, inputs, out, *args):
    subprocess.run(
        [str(stipple_cli), "render", *map(str, inputs), "-o", str(out), *map(str, args)],
        check=True, capture_output=True, text=True,
    )
    return read_png(out)


def assert_same_image(got, expected):
    assert got.dtype == np.uint8 and got.shape == expected.shape
    # The content is not the background only (the comparison would be empty otherwise).
    background = expected[0, 0]
    covered = np.any(expected != background, axis=2).mean()
    assert covered > 0.05, f"only {covered:.1%} of the reference is drawn"
    # Pixel-exact: one pipeline, one device, the same points in the same order.
    np.testing.assert_array_equal(got, expected)


W, H = 200, 150


def test_render_of_read_points_equals_cli(data, stipple_cli, tmp_path):
    path = data / "las" / "autzen_trim.las"
    points = stipple.read(path)
    # Framed from the data (azimuth/elevation), and from an explicit camera.
    expected = cli_render(stipple_cli, [path], tmp_path / "auto.png", "--width", W, "--height", H)
    assert_same_image(stipple.render(points, W, H), expected)
    lo, hi = np.array([points["x"].min(), points["y"].min(), points["z"].min()]), np.array(
        [points["x"].max(), points["y"].max(), points["z"].max()]
    )
    center = (lo + hi) / 2
    eye = center + np.array([-400.0, -900.0, 700.0])
    camera = ",".join(repr(float(v)) for v in (*eye, *center))
    expected = cli_render(
        stipple_cli, [path], tmp_path / "cam.png", "--width", W, "--height", H,
        "--camera", camera, "--color", "intensity", "--renderer", "billboard",
    )
    got = stipple.render(
        points, W, H, camera=(eye, center), color="intensity", renderer="billboard"
    )
    assert_same_image(got, expected)
    # A path renders the same as the CLI too (here the LAZ of the same points).
    laz = data / "laz" / "autzen_trim.laz"
    expected = cli_render(
        stipple_cli, [laz], tmp_path / "laz.png", "--width", W, "--height", H,
        "--color", "classification", "--point-size", 3,
    )
    assert_same_image(
        stipple.render(laz, W, H, color="classification", point_size=3), expected
    )


def test_render_of_xyz_array_equals_cli(stipple_cli, tmp_path):
    # Generated points: a tilted, bumpy surface with a tower (no test data needed).
    rng = np.random.default_rng(3)
    n = 40000
    x, y = rng.uniform(0, 200, n), rng.uniform(0, 150, n)
    z = 0.1 * x + 5 * np.sin(x / 15) * np.cos(y / 20)
    tower = (np.abs(x - 120) < 10) & (np.abs(y - 70) < 10)
    z[tower] += rng.uniform(0, 40, tower.sum())
    header = laspy.LasHeader(point_format=0, version="1.2")
    header.scales = np.array([0.001, 0.001, 0.001])
    header.offsets = np.array([500000.0, 4000000.0, 0.0])
    las = laspy.LasData(header)
    las.x, las.y, las.z = x + 500000.0, y + 4000000.0, z
    path = tmp_path / "gen.las"
    las.write(path)
    xyz = np.column_stack([np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)])
    for renderer in ("billboard", "compute"):
        expected = cli_render(
            stipple_cli, [path], tmp_path / f"{renderer}.png", "--width", W, "--height", H,
            "--color", "elevation", "--renderer", renderer, "--azimuth", 120, "--elevation", 30,
        )
        got = stipple.render(
            xyz, W, H, color="elevation", renderer=renderer, azimuth=120, elevation=30
        )
        assert_same_image(got, expected)
        # The same from the file's path.
        np.testing.assert_array_equal(
            stipple.render(path, W, H, color="elevation", renderer=renderer, azimuth=120,
                           elevation=30),
            expected,
        )


def test_render_options_change_the_image():
    rng = np.random.default_rng(5)
    xyz = rng.uniform(0, 100, (20000, 3))
    grey = stipple.render(xyz, 64, 48, color="constant", constant_color=(0.5, 0.5, 0.5),
                          background=(1, 0, 0), edl=False, point_size=2)
    assert grey.shape == (48, 64, 4) and grey.dtype == np.uint8
    assert (grey[..., 3] == 255).all()
    red = np.all(grey[..., :3] == (255, 0, 0), axis=2)
    drawn = np.all(np.abs(grey[..., :3].astype(int) - 128) <= 2, axis=2)
    assert red.any() and drawn.mean() > 0.2 and (red | drawn).mean() > 0.95


def test_render_errors_name_the_problem(tmp_path):
    with pytest.raises(stipple.Error, match="missing.las"):
        stipple.render(tmp_path / "missing.las", 32, 32)
    bad = tmp_path / "bad.las"
    bad.write_bytes(b"LASF" + bytes(50))
    with pytest.raises(stipple.Error, match="bad.las"):
        stipple.render(bad, 32, 32)
    with pytest.raises(stipple.Error, match="renderer 'fast'"):
        stipple.render(np.zeros((3, 3)), 32, 32, renderer="fast")
    with pytest.raises(stipple.Error, match="not finite"):
        stipple.render(np.array([[0, 0, 0], [1, np.nan, 1.0]]), 32, 32)
    with pytest.raises(ValueError, match="shape"):
        stipple.render(np.zeros((4, 2)), 32, 32)
