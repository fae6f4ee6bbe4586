"""stipple.read on Gaussian splat files: a dict of float32 arrays (SplatSet's fields)."""

import numpy as np
import pytest

import stipple
from conftest import DATA


def test_read_splats_arrays():
    ply = DATA / "splats" / "gaussiansplats3d-pr477" / "lod5_tile_0.ply"
    if not ply.exists():
        pytest.skip(f"{ply} is absent (the real test data lives in ../shared/data)")
    s = stipple.read(ply)
    assert s["format"] == "INRIA PLY"
    assert s["sh_degree"] == 3
    n = 111
    for key, shape in [("positions", (n, 3)), ("scales", (n, 3)), ("rotations", (n, 4)),
                       ("opacities", (n,)), ("sh_dc", (n, 3)), ("sh_rest", (n, 15, 3))]:
        assert s[key].shape == shape, key
        assert s[key].dtype == np.float32, key
    np.testing.assert_allclose(np.linalg.norm(s["rotations"], axis=1), 1.0, atol=1e-5)
    # Splat 5 as the file stores it (raw floats): x y z, logit opacity, log scale, w x y z.
    np.testing.assert_allclose(s["positions"][5], [2.8651986, 3.7422662, 4.7787480], rtol=1e-6)
    np.testing.assert_allclose(s["opacities"][5], 1 / (1 + np.exp(1.2015115)), rtol=1e-5)
    np.testing.assert_allclose(s["scales"][5, 0], np.exp(-1.7474055), rtol=1e-5)
    q = np.array([0.29227456, 0.31505269, 0.57389545, 0.94085699])
    np.testing.assert_allclose(s["rotations"][5], q / np.linalg.norm(q), rtol=1e-5)
    # A PLY's frame (y down, z forward) turned half a turn about x into the Y-up frame.
    assert np.allclose(s["transform"], np.diag([1.0, -1.0, -1.0, 1.0]))
    with pytest.raises(stipple.Error):
        stipple.read(ply, fields=["x"])
