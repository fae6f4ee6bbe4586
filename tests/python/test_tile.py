"""stipple.tile, split tiling (subset + merge) and stipple.dask.tile on a LocalCluster."""

import json
import os
import signal
import subprocess

import pytest

import stipple


def tileset_summary(stipple_cli, path):
    """`stipple info --json` on a tileset: points declared by the tile headers, tiles, and the
    root bounding box from tileset.json."""
    out = subprocess.run(
        [str(stipple_cli), "info", str(path / "tileset.json"), "--json"],
        check=True, capture_output=True, text=True,
    ).stdout
    info = json.loads(out)
    root = json.loads((path / "tileset.json").read_text())["root"]
    return info["points"], info["tiles"], root["boundingVolume"]["box"]


def test_tile_with_progress_and_errors(data, tmp_path):
    calls = []
    stats = stipple.tile(
        data / "laz" / "autzen_trim.laz", tmp_path / "t", max_node_points=1000, threads=2,
        progress=lambda phase, done, total: calls.append((phase, done, total)),
    )
    assert stats["points"] == 110000 and stats["tiles"] > 100
    assert ("reading", 110000, 110000) in calls and calls[-1] == ("indexing", 110000, 110000)
    assert (tmp_path / "t" / "tileset.json").exists()

    def stop(phase, done, total):
        raise KeyError("stop here")

    with pytest.raises(KeyError, match="stop here"):
        stipple.tile(data / "las" / "autzen_trim.las", tmp_path / "u", progress=stop)
    assert not (tmp_path / "u").exists()
    with pytest.raises(stipple.Error, match="exists; pass --force"):
        stipple.tile(data / "las" / "autzen_trim.las", tmp_path / "t")
    with pytest.raises(stipple.Error, match="'3/5' is not I/N"):
        stipple.tile(data / "las" / "autzen_trim.las", tmp_path / "v", subset="3/5")


@pytest.mark.parametrize("parts", [4, 8, 16])
def test_subset_merge_equals_one_run(data, tmp_path, stipple_cli, parts):
    src = data / "laz" / "autzen_trim.laz"
    stipple.tile(src, tmp_path / "one", max_node_points=1000, threads=2)
    dirs = []
    for i in range(parts):
        dirs.append(tmp_path / f"part{i}")
        stipple.tile(src, dirs[-1], max_node_points=1000, threads=2, subset=f"{i}/{parts}")
    with pytest.raises(stipple.Error, match=f"missing {parts - 1}/{parts}"):
        stipple.merge(dirs[:-1], tmp_path / "bad")
    stats = stipple.merge(dirs, tmp_path / "merged")
    assert stats["points"] == 110000
    one = tileset_summary(stipple_cli, tmp_path / "one")
    merged = tileset_summary(stipple_cli, tmp_path / "merged")
    assert merged[0] == one[0] == 110000
    assert merged[2] == pytest.approx(one[2], abs=1e-9)
    # The parts are intact: the merge can run again (a retried merge task).
    stipple.merge(dirs, tmp_path / "merged", force=True)


def test_dask_tile_survives_a_killed_worker(data, tmp_path, stipple_cli):
    distributed = pytest.importorskip("distributed")
    import stipple.dask

    src = data / "laz" / "autzen_trim.laz"
    stipple.tile(src, tmp_path / "one", max_node_points=1000, threads=1)
    marker = tmp_path / "killed-once"

    # Runs on the workers (pickled by value): the first part to report progress kills its own
    # worker process, mid-task, with SIGKILL; the scheduler must run that part again elsewhere.
    def kill_once(phase, done, total, marker=str(marker)):
        if phase == "reading" and not os.path.exists(marker):
            open(marker, "w").close()
            os.kill(os.getpid(), signal.SIGKILL)

    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
        silence_logs=50,
    ) as cluster, distributed.Client(cluster) as client:
        scratch = tmp_path / "scratch"  # the caller's folder: what is in it stays
        scratch.mkdir()
        (scratch / "keep.txt").write_text("mine")
        stats = stipple.dask.tile(
            [src], tmp_path / "dask", client, parts=4, max_node_points=1000, threads=1,
            progress=kill_once, work_dir=scratch,
        )
    assert marker.exists()  # a worker was killed during a part
    assert stats["points"] == 110000
    one = tileset_summary(stipple_cli, tmp_path / "one")
    split = tileset_summary(stipple_cli, tmp_path / "dask")
    assert split[0] == one[0]
    assert split[2] == pytest.approx(one[2], abs=1e-9)
    assert sorted(p.name for p in scratch.iterdir()) == ["keep.txt"]
