"""stipple.read / read_header / info against laspy 2.x, field by field."""

import laspy
import numpy as np
import pytest

import stipple


def assert_same_as_laspy(path):
    points = stipple.read(path)
    las = laspy.read(path)
    assert len(points) == len(las.points)
    checked = 0
    for name in las.point_format.dimension_names:
        assert name in points.dtype.names, f"{path}: no field {name}"
        expected = np.asarray(las[name])
        np.testing.assert_array_equal(points[name], expected, err_msg=f"{path}: {name}")
        checked += 1
    for axis in "xyz":
        assert points[axis].dtype == np.float64
        np.testing.assert_array_equal(points[axis], np.asarray(getattr(las, axis)))
    return points, checked


@pytest.mark.parametrize(
    "name",
    ["las/autzen_trim.las", "laz/autzen_trim.laz", "las/test1_4.las", "laz/lone-star.copc.laz"],
)
def test_read_equals_laspy(data, name):
    points, checked = assert_same_as_laspy(data / name)
    assert checked >= 15


def test_format_8_and_10_with_extra_bytes(tmp_path):
    rng = np.random.default_rng(7)
    for fmt in (8, 10):
        n = 3000
        header = laspy.LasHeader(point_format=fmt, version="1.4")
        header.scales = np.array([0.01, 0.01, 0.001])
        header.offsets = np.array([500000.0, 4000000.0, 0.0])
        header.add_extra_dims(
            [
                laspy.ExtraBytesParams("height", "int16", scales=np.array([0.01]), offsets=np.array([5.0])),
                laspy.ExtraBytesParams("confidence", "uint8"),
                laspy.ExtraBytesParams("normal", "3f4"),
                laspy.ExtraBytesParams("amplitude", "float64"),
            ]
        )
        las = laspy.LasData(header)
        las.x = 500000 + rng.uniform(0, 1000, n)
        las.y = 4000000 + rng.uniform(0, 1000, n)
        las.z = rng.uniform(0, 300, n)
        las.intensity = rng.integers(0, 65535, n)
        las.return_number = rng.integers(1, 16, n)
        las.number_of_returns = rng.integers(1, 16, n)
        las.classification = rng.integers(0, 256, n)
        las.synthetic = rng.integers(0, 2, n)
        las.overlap = rng.integers(0, 2, n)
        las.scanner_channel = rng.integers(0, 4, n)
        las.edge_of_flight_line = rng.integers(0, 2, n)
        las.scan_angle = rng.integers(-30000, 30000, n)
        las.user_data = rng.integers(0, 256, n)
        las.point_source_id = rng.integers(0, 65535, n)
        las.gps_time = rng.uniform(0, 1e6, n)
        las.red = rng.integers(0, 65535, n)
        las.green = rng.integers(0, 65535, n)
        las.blue = rng.integers(0, 65535, n)
        las.nir = rng.integers(0, 65535, n)
        las.height = rng.uniform(-300, 300, n)
        las.confidence = rng.integers(0, 256, n)
        las.normal = rng.uniform(-1, 1, (n, 3)).astype(np.float32)
        las.amplitude = rng.normal(size=n)
        if fmt == 10:
            las.wavepacket_index = rng.integers(0, 255, n)
            las.wavepacket_offset = rng.integers(0, 1 << 40, n)
            las.wavepacket_size = rng.integers(0, 1 << 31, n)
            las.return_point_wave_location = rng.normal(size=n).astype(np.float32)
            las.x_t = rng.normal(size=n).astype(np.float32)
        path = tmp_path / f"f{fmt}.las"
        las.write(path)
        points, _ = assert_same_as_laspy(path)
        assert points["height"].dtype == np.float64  # scaled extra bytes, as laspy gives them
        assert points["normal"].shape == (n, 3)
        assert stipple.read_header(path)["extra_bytes"][0]["name"] == "height"


def test_fields_subset_and_order(data):
    points = stipple.read(data / "las" / "autzen_trim.las", fields=["classification", "x", "red"])
    assert points.dtype.names == ("classification", "x", "red")
    with pytest.raises(stipple.Error, match="autzen_trim.las: no field 'nope'"):
        stipple.read(data / "las" / "autzen_trim.las", fields=["nope"])


def test_header_and_info(data):
    path = data / "laz" / "lone-star.copc.laz"
    header = stipple.read_header(path)
    las = laspy.read(path)
    assert header["point_count"] == las.header.point_count == 518862
    assert header["copc"] and header["compressed"] and header["point_format"] == 6
    assert header["scale"] == pytest.approx(list(las.header.scales))
    assert header["min"] == pytest.approx(list(las.header.mins))
    info = stipple.info(data / "las" / "autzen_trim.las")
    assert info["point_count"] == 110000 and info["version"] == "1.2"


def test_truncated_file_raises_with_its_name(data, tmp_path):
    for name in ("las/autzen_trim.las", "laz/autzen_trim.laz"):
        raw = (data / name).read_bytes()
        cut = tmp_path / ("cut-" + name.split("/")[1])
        cut.write_bytes(raw[: len(raw) * 2 // 3])
        with pytest.raises(stipple.Error, match=str(cut.name)):
            stipple.read(cut)
    with pytest.raises(stipple.Error, match="missing.las"):
        stipple.read(tmp_path / "missing.las")
    with pytest.raises(stipple.Error, match="short.las"):
        (tmp_path / "short.las").write_bytes(b"LASF" + bytes(100))
        stipple.read_header(tmp_path / "short.las")


def test_declared_count_beyond_the_file_raises_before_allocating(tmp_path):
    # A valid file whose header then claims 4 billion points (LAS 1.2: the 32-bit count at byte
    # 107): reading must fail with the file's name, not try to allocate ~200 GB first.
    header = laspy.LasHeader(point_format=3, version="1.2")
    las = laspy.LasData(header)
    las.x, las.y, las.z = np.arange(100.0), np.arange(100.0), np.arange(100.0)
    for suffix in ("las", "laz"):
        path = tmp_path / f"crafted.{suffix}"
        las.write(path)
        raw = bytearray(path.read_bytes())
        raw[107:111] = (4_000_000_000).to_bytes(4, "little")
        path.write_bytes(bytes(raw))
        with pytest.raises(stipple.Error, match=f"crafted.{suffix}.*4000000000"):
            stipple.read(path)
