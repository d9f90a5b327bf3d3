"""ice-batch: one record per input, isolation of failures, resumable reruns, Dask workers."""
import json
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import ice
import ice.batch as batch
from conftest import extended_meshes

MESHES = ["spot.obj", "bear.off", "elephant-with-holes.off", "blobby_3cc.off", "fandisk.off", "lion-head.off"]
NON_MANIFOLD_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 1 1 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n"


@pytest.fixture()
def dataset(tmp_path, project_mesh):
    """A folder of real meshes in two subfolders, a defective file, an unreadable one and a non-mesh."""
    root = tmp_path / "in"
    for i, name in enumerate(MESHES):
        target = root / ("a" if i % 2 else "b") / name
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(project_mesh(name), target)
    (root / "b" / "broken.obj").write_text(NON_MANIFOLD_OBJ)
    (root / "b" / "truncated.off").write_text("OFF\n4 2 0\n0 0 0\n1 0 0\n")
    (root / "notes.txt").write_text("not a mesh\n")
    return root


def options(**coarsen):
    return batch.BatchOptions(coarsen=coarsen or {"ratio": 0.05}, workers=2, progress=False)


def test_one_record_per_input_and_outputs_read_back(dataset, tmp_path):
    out = tmp_path / "out"
    result = batch.run(str(dataset), out, options())
    assert len(result.records) == len(MESHES) + 2 and result.skipped == 0
    by_name = {pathlib.Path(r["output"]).name: r for r in result.records}
    assert by_name["broken.obj"]["error_kind"] == "defective" and "non-manifold" in by_name["broken.obj"]["error"]
    assert by_name["truncated.off"]["error_kind"] == "unreadable"
    assert str(dataset / "b" / "broken.obj") in by_name["broken.obj"]["error"]  # the tools' message names the file
    for name in MESHES:
        record = by_name[name]
        assert record["status"] == "ok" and record["coarse_vertices"] >= int(np.ceil(0.05 * record["vertices"]))
        loaded = batch.load_result(out, record["output"])
        # the same coarse space as ice.coarsen in this process, to the last bit
        V, F = ice.load_mesh(record["input"])
        direct = ice.coarsen(V, F, ratio=0.05)
        assert abs(loaded["P"] - direct.P).max() == 0
        assert np.array_equal(loaded["coarse"].lengths, direct.lengths)
        assert np.array_equal(loaded["map_face"], direct.map[0])
    # On shared cores the largest meshes (one per worker) go first: the others ran at the lowest
    # priority, when the batch gave a mesh more than one thread (2+ cores).
    ran = sorted((r for r in result.records if "nice" in r), key=lambda r: -r["input_size"])
    if ran and ran[0]["threads"] > 1:
        base = os.getpriority(os.PRIO_PROCESS, 0)
        assert [r["nice"] for r in ran] == [base] * 2 + [max(base, batch.YIELDING_NICE)] * (len(ran) - 2)
        if hasattr(os, "SCHED_IDLE") and os.sched_getscheduler(0) == os.SCHED_OTHER:
            assert [r["policy"] for r in ran] == ["other"] * 2 + ["idle"] * (len(ran) - 2)
    # the output tree mirrors the input; records.jsonl and summary.csv list every input
    assert (out / "a" / "bear.off.ilm").exists() and (out / "b" / "spot.obj.npz").exists()
    assert len((out / "records.jsonl").read_text().splitlines()) == len(MESHES) + 2
    assert len((out / "summary.csv").read_text().splitlines()) == len(MESHES) + 3
    assert not list(out.rglob("*.part"))  # no temporary left


def test_a_yielding_mesh_fails_with_its_own_error(project_mesh, tmp_path):
    """A mesh run at low priority on a thread of its own raises what it raises on the worker's
    thread: here the record cannot be written (the output folder lies under a file)."""
    blocker = tmp_path / "file"
    blocker.write_text("")
    mesh = project_mesh("spot.obj")
    stat = os.stat(mesh)
    for yielding in (False, True):
        with pytest.raises(OSError):
            batch.coarsen_file(str(mesh), "spot.obj", str(blocker / "out"), {"ratio": 0.1}, False, None,
                               stat.st_size, stat.st_mtime_ns, 1, yielding)


def test_rerun_skips_and_changed_option_redoes(dataset, tmp_path):
    out = tmp_path / "out"
    first = batch.run(str(dataset), out, options())
    again = batch.run(str(dataset), out, options())
    assert again.skipped == len(first.records)  # no work: even the refused files are not retried
    assert [r["hash"] for r in again.records] == [r["hash"] for r in first.records]
    changed = batch.run(str(dataset), out, options(ratio=0.1))
    assert changed.skipped == 0
    assert all(r["hash"] != first.records[0]["hash"] for r in changed.records)
    assert all(r["coarse_vertices"] == int(np.ceil(0.1 * r["vertices"])) for r in changed.records
               if r["status"] == "ok" and r["target_reached"])
    # an input that changed is redone, alone
    (dataset / "a" / "bear.off").touch()
    os.utime(dataset / "a" / "bear.off", ns=(time.time_ns(), time.time_ns() + 10**9))
    touched = batch.run(str(dataset), out, options(ratio=0.1))
    assert touched.skipped == len(first.records) - 1


def test_large_mesh_result_does_not_depend_on_workers_or_threads(project_mesh, tmp_path):
    """A mesh of 20,000+ vertices runs ICE's parallel phase with a fixed region count: one worker (one
    thread per mesh) and two workers (two threads per mesh) give the same result to the bit, which is
    ice.coarsen's by default, on any number of threads."""
    V, F = ice.loop_subdivide(*ice.load_mesh(project_mesh("spot.obj")), 2)  # 46,850 vertices
    folder = tmp_path / "in"
    folder.mkdir()
    ice.save_mesh(folder / "big.ply", V, F, binary=True)
    results = {}
    # Workers spawned afresh and forked from a server process (the default on Linux) give the same files.
    for workers, method in ((1, "spawn"), (2, "spawn"), (2, "forkserver")):
        out = tmp_path / f"out{workers}{method}"
        run = batch.run(str(folder), out, batch.BatchOptions(coarsen={"ratio": 0.05}, workers=workers, progress=False,
                                                             start_method=method))
        assert run.records[0]["status"] == "ok" and run.records[0]["threads"] == workers
        results[workers, method] = batch.load_result(out, "big.ply")
    assert len({result["record"]["hash"] for result in results.values()}) == 1  # the threads are not an option
    V, F = ice.load_mesh(folder / "big.ply")
    direct = ice.coarsen(V, F, ratio=0.05)  # the library's default regions, on this machine's threads
    assert direct.summary["parallel_removed"] > direct.summary["removed"] // 2
    for result in results.values():
        assert abs(result["P"] - direct.P).max() == 0
        assert np.array_equal(result["coarse"].lengths, direct.lengths)
        assert np.array_equal(result["map_face"], direct.map[0])
    assert np.array_equal(ice.coarsen(V, F, ratio=0.05, regions=ice.DEFAULT_COARSENING_REGIONS, threads=1).lengths,
                          direct.lengths)
    # the exact serial order is one region; 0 is the default count spelled out: the same run and hash
    serial = batch.run(str(folder), tmp_path / "serial", options(ratio=0.05, regions=1))
    assert serial.records[0]["coarse_vertices"] == direct.n_vertices
    assert not np.array_equal(batch.load_result(tmp_path / "serial", "big.ply")["coarse"].lengths, direct.lengths)
    zero = batch.run(str(folder), tmp_path / "zero", options(ratio=0.05, regions=0))
    assert zero.records[0]["hash"] == results[1, "spawn"]["record"]["hash"]
    with pytest.raises(ValueError, match="mesh_threads"):
        batch.run(str(folder), tmp_path / "bad", options(ratio=0.05, threads=2))
    with pytest.raises(ValueError, match="start method"):
        batch.run(str(folder), tmp_path / "bad", batch.BatchOptions(coarsen={"ratio": 0.05}, start_method="fork"))
    assert not (tmp_path / "bad").exists()
    command = [sys.executable, "-m", "ice.batch", str(folder), "-o", str(tmp_path / "bad"), "--ratio", "0.05",
               "--mesh-threads", "0"]
    refused = subprocess.run(command, capture_output=True, text=True)
    assert refused.returncode == 4 and "threads per mesh" in refused.stderr


def test_foreign_files_are_not_replaced(dataset, tmp_path):
    out = tmp_path / "out"
    (out / "a").mkdir(parents=True)
    (out / "a" / "bear.off.ilm").write_text("mine\n")
    with pytest.raises(FileExistsError, match="--force"):
        batch.run(str(dataset), out, options())
    assert (out / "a" / "bear.off.ilm").read_text() == "mine\n"
    result = batch.run(str(dataset), out, batch.BatchOptions(coarsen={"ratio": 0.05}, workers=2, progress=False,
                                                             force=True))
    assert all(r["status"] == "ok" for r in result.records if r["output"].endswith("bear.off"))


def test_manifest_forms(dataset, tmp_path):
    jobs, _ = batch.manifest(str(dataset))
    assert len(jobs) == len(MESHES) + 2
    jobs, _ = batch.manifest(str(dataset / "**" / "*.off"))
    assert sorted(pathlib.Path(j.relative).name for j in jobs) == sorted(
        [m for m in MESHES if m.endswith(".off")] + ["truncated.off"])
    listing = tmp_path / "list.txt"
    listing.write_text("# two meshes and a missing one\nin/a/bear.off\nin/b/spot.obj\nin/missing.ply\n")
    out = tmp_path / "from_list"
    result = batch.run(str(listing), out, options())
    assert [r["status"] for r in result.records] == ["ok", "ok", "error"]
    assert result.records[2]["error_kind"] == "unreadable"
    with pytest.raises(ValueError, match="no meshes found"):
        batch.manifest(str(tmp_path / "nothing" / "*.obj"))


def test_killed_batch_loses_no_mesh(dataset, tmp_path):
    """The whole batch killed mid-way (SIGKILL of its process group): the rerun does exactly the rest."""
    out = tmp_path / "out"
    command = [sys.executable, "-m", "ice.batch", str(dataset), "-o", str(out), "--ratio", "0.05", "-q",
               "--workers", "1"]
    process = subprocess.Popen(command, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while time.time() < deadline and len(list(out.rglob("*.json"))) < 2:
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    done_before = {p.relative_to(out) for p in out.rglob("*.json")}
    assert 2 <= len(done_before) < len(MESHES) + 2, "the batch was to be killed mid-way"
    result = batch.run(str(dataset), out, options())
    assert result.skipped == len(done_before)
    assert len(result.records) == len(MESHES) + 2 and not list(out.rglob("*.part"))
    assert sum(r["status"] == "ok" for r in result.records) == len(MESHES)


def busy_worker(psutil, process, out, seconds=120):
    """A Dask worker process of the batch `process` busy coarsening (None if none is found in time):
    once a first record exists the workers are up (a worker stopped while Dask still starts it is
    another case); a worker is a busy child of the batch (spawned, or forked from a fork server),
    not its resource tracker."""
    deadline = time.time() + seconds
    while time.time() < deadline and process.poll() is None:
        if not list(out.rglob("*.json")):
            time.sleep(0.02)
            continue
        for child in psutil.Process(process.pid).children(recursive=True):
            try:
                if "resource_tracker" not in " ".join(child.cmdline()) and child.cpu_percent(interval=0.05) > 50:
                    return child
            except psutil.Error:
                continue
    return None


def test_worker_killed_mid_batch_loses_no_mesh(dataset, tmp_path):
    """One Dask worker process killed while it coarsens: Dask reruns its task elsewhere."""
    psutil = pytest.importorskip("psutil")
    # A mesh large enough (47k vertices, ~1 s) to be still coarsening when the first record appears.
    V, F = ice.loop_subdivide(*ice.load_mesh(dataset / "b" / "spot.obj"), 2)
    ice.save_mesh(dataset / "big.ply", V, F, binary=True)
    out = tmp_path / "out"
    command = [sys.executable, "-m", "ice.batch", str(dataset), "-o", str(out), "--ratio", "0.05", "-q",
               "--workers", "2"]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    worker = busy_worker(psutil, process, out)
    assert worker is not None, "no busy worker was found to kill"
    worker.kill()  # a worker busy a moment ago has not finished a batch of several meshes
    stdout, stderr = process.communicate(timeout=300)
    records = [json.loads(line) for line in (out / "records.jsonl").read_text().splitlines()]
    assert len(records) == len(MESHES) + 3
    assert sum(r["status"] == "ok" for r in records) == len(MESHES) + 1, stdout + stderr


def test_shared_meshes(tmp_path):
    folder = extended_meshes()
    if not folder.is_dir():
        pytest.skip(f"the shared mesh set is not at {folder} (set ICE_EXTENDED_MESHES)")
    result = batch.run(str(folder), tmp_path / "out", batch.BatchOptions(coarsen={"ratio": 0.05}, repair=True,
                                                                         workers=2, progress=False))
    inputs = [p for p in folder.rglob("*") if p.suffix.lower() in batch.MESH_EXTENSIONS]
    assert len(result.records) == len(inputs)
    for record in result.records:
        assert record["status"] == "ok" or record["error"], record


def test_timeout_is_recorded_and_retried(dataset, tmp_path):
    out = tmp_path / "out"
    hurried = batch.BatchOptions(coarsen={"ratio": 0.05}, workers=2, progress=False, timeout=1e-9)
    result = batch.run(str(dataset), out, hurried)
    timed_out = [r for r in result.records if r.get("error_kind") == "timeout"]
    assert len(timed_out) == len(MESHES)  # every mesh needs over 1,000 removals, the first progress report
    assert all("timeout" in r["error"] and r["input"] in r["error"] for r in timed_out)
    again = batch.run(str(dataset), out, options())  # a timeout is not the input's fault: redone
    assert again.skipped == 2 and sum(r["status"] == "ok" for r in again.records) == len(MESHES)


def test_stalled_worker_does_not_hang_the_batch(dataset, tmp_path):
    """A worker frozen while it coarsens (SIGSTOP: alive to Dask, doing nothing): once no mesh has
    finished for --stall-timeout seconds the batch records what it still waits for as stalled and
    ends; a rerun retries exactly those meshes."""
    psutil = pytest.importorskip("psutil")
    # Three meshes of a few seconds, started first (largest first): the worker found busy after the
    # first record is on one of them, so it is frozen holding a running task.
    V, F = ice.loop_subdivide(*ice.load_mesh(dataset / "b" / "spot.obj"), 3)
    for copy in range(3):
        ice.save_mesh(dataset / f"big{copy}.ply", V, F, binary=True)
    out = tmp_path / "out"
    stall = 8.0
    command = [sys.executable, "-m", "ice.batch", str(dataset), "-o", str(out), "--ratio", "0.05", "-q",
               "--workers", "2", "--stall-timeout", str(stall)]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    frozen = busy_worker(psutil, process, out)
    try:
        assert frozen is not None, "no busy worker was found to freeze"
        frozen.suspend()
        stopped_at = time.time()
        stdout, stderr = process.communicate(timeout=stall + 120)
        assert time.time() - stopped_at < stall + 90, "the batch waited far past its stall timeout"
    finally:
        if frozen is not None:
            try:
                frozen.kill()
            except psutil.Error:
                pass
        if process.poll() is None:
            process.kill()
    assert process.returncode == 5, stdout + stderr  # not every mesh is done
    records = [json.loads(line) for line in (out / "records.jsonl").read_text().splitlines()]
    assert len(records) == len(MESHES) + 5
    stalled = [r for r in records if r.get("error_kind") == "stalled"]
    assert stalled and all("stall" in r["error"] and r["input"] in r["error"] for r in stalled), stdout + stderr
    # Every good mesh is done or stalled; the two bad files are refused, or stalled when the stall came
    # before their turn (under load: seen once beside a CPU-bound job).
    bad = {"broken.obj", "truncated.off"}
    good_stalled = [r for r in stalled if pathlib.Path(r["input"]).name not in bad]
    assert sum(r["status"] == "ok" for r in records) + len(good_stalled) == len(MESHES) + 3
    for r in records:
        if pathlib.Path(r["input"]).name in bad:
            assert r["error_kind"] in ("defective", "unreadable", "stalled"), r
    again = batch.run(str(dataset), out, options())
    assert again.skipped == len(MESHES) + 5 - len(stalled)
    assert sum(r["status"] == "ok" for r in again.records) == len(MESHES) + 3


def test_spectral_features(project_mesh, tmp_path, monkeypatch):
    """--features eigs:K,hks:...: the eigenbasis through each mesh's coarse proxy beside its coarse space
    (M-orthonormal on the input mesh, one zero mode); the features are part of the options hash. The
    batch's records are its store: nothing goes into the user's store of set-ups."""
    store = tmp_path / "store"
    monkeypatch.setenv("ICE_CACHE", str(store))
    root = tmp_path / "in"
    root.mkdir()
    for name in ("spot.obj", "bear.off"):
        shutil.copy(project_mesh(name), root / name)
    out = tmp_path / "out"
    features = batch.parse_features("eigs:8,hks:0.01:0.1")
    assert features == {"eigs": 8, "hks": [0.01, 0.1]}
    result = batch.run(str(root), out, batch.BatchOptions(coarsen={"ratio": 0.05}, features=features, workers=2,
                                                          progress=False))
    assert all(r["status"] == "ok" for r in result.records)
    loaded = batch.load_result(out, "spot.obj")
    values, vectors = loaded["eigenvalues"], loaded["eigenvectors"]
    V, F = ice.load_mesh(project_mesh("spot.obj"))
    assert vectors.shape == (len(V), 8) and loaded["hks"].shape == (len(V), 2)
    Fi, lengths, _ = ice.intrinsic_delaunay(V, F)
    M = ice.mass_matrix(F=Fi, lengths=lengths, n=len(V))
    assert np.abs(vectors.T @ (M @ vectors) - np.eye(8)).max() < 1e-8
    assert abs(values[0]) < 1e-8 and np.all(np.diff(values) >= 0) and values[1] > 1e-3
    np.testing.assert_allclose(loaded["hks"], ice.heat_kernel_signature(values, vectors, [0.01, 0.1]), rtol=1e-12)
    assert not store.exists() or not any(store.iterdir())
    # Other features redo every mesh; the same skip them.
    assert batch.run(str(root), out, batch.BatchOptions(coarsen={"ratio": 0.05}, features=features, workers=2,
                                                        progress=False)).skipped == 2
    again = batch.run(str(root), out, batch.BatchOptions(coarsen={"ratio": 0.05}, features={"eigs": 4}, workers=2,
                                                         progress=False))
    assert again.skipped == 0
    with pytest.raises(ValueError, match="give eigs"):
        batch.parse_features("hks:0.1")
    with pytest.raises(ValueError, match="unknown feature"):
        batch.parse_features("wks:1")


def test_nonmanifold_meshes_and_point_sets_on_their_cover(project_mesh, tmp_path):
    """nonmanifold="tufted" (--nonmanifold tufted): a point set and a non-manifold mesh are solved on their
    tufted cover (no .ilm for them, P and the eigenbasis written, one row per point or vertex); a manifold
    mesh is coarsened as without the option; without it both are refused, deterministically."""
    root = tmp_path / "in"
    root.mkdir()
    for name in ("kitten.xyz", "triple_vierbein.obj", "spot.obj"):
        shutil.copy(project_mesh(name), root / name)
    out = tmp_path / "out"
    # Without the option point sets are not in the manifest, a non-manifold mesh is refused.
    refused = batch.run(str(root), out, batch.BatchOptions(coarsen={"ratio": 0.1}, workers=1, progress=False))
    kinds = {pathlib.Path(r["input"]).name: r.get("error_kind") for r in refused.records}
    assert kinds == {"triple_vierbein.obj": "defective", "spot.obj": None}
    with pytest.raises(ValueError, match="nonmanifold must be"):
        batch.run(str(root), out, batch.BatchOptions(coarsen={"ratio": 0.1, "nonmanifold": "tufted_cover"}, progress=False))
    covered = batch.run(str(root), out, batch.BatchOptions(coarsen={"ratio": 0.1, "nonmanifold": "tufted"},
                                                           features={"eigs": 6}, repair=True, workers=1,
                                                           progress=False))
    assert all(r["status"] == "ok" for r in covered.records), covered.records
    cloud = batch.load_result(out, "kitten.xyz")
    assert cloud["record"]["tufted_cover"] and cloud["record"]["point_cloud"] and cloud["coarse"] is None
    assert cloud["P"].shape[0] == 5210 and cloud["eigenvectors"].shape == (5210, 6)
    assert np.allclose(cloud["P"] @ np.ones(cloud["P"].shape[1]), 1, atol=1e-12)
    values = cloud["eigenvalues"]
    assert abs(values[0]) < 1e-8 * values[-1] and values[1] > 1e-6 * values[-1]
    assert not (out / "kitten.xyz.ilm").exists()
    mesh = batch.load_result(out, "spot.obj")
    assert not mesh["record"]["tufted_cover"] and mesh["coarse"] is not None
    # Up to date on a rerun (the missing .ilm of a covered mesh is not a missing output), also when
    # separate_thin_parts is given as its default.
    assert batch.run(str(root), out, batch.BatchOptions(coarsen={"ratio": 0.1, "nonmanifold": "tufted",
                                                                 "separate_thin_parts": False},
                                                        features={"eigs": 6}, repair=True, workers=1,
                                                        progress=False)).skipped == 3
    # separate_thin_parts reaches the point set's fans (the loader's, not ice.coarsen's option).
    with pytest.raises(ValueError, match="separate_thin_parts must be"):
        batch.run(str(root), out, batch.BatchOptions(coarsen={"ratio": 0.1, "separate_thin_parts": 1}, progress=False))
    with pytest.raises(ValueError, match="nonmanifold='tufted' only"):
        batch.run(str(root), out, batch.BatchOptions(coarsen={"ratio": 0.1, "separate_thin_parts": True}, progress=False))
    apart = batch.run(str(root), out, batch.BatchOptions(coarsen={"ratio": 0.1, "nonmanifold": "tufted",
                                                                  "separate_thin_parts": True},
                                                         repair=True, workers=1, progress=False))
    assert all(r["status"] == "ok" for r in apart.records) and apart.skipped == 0
    V, F = ice.load_mesh(project_mesh("kitten.xyz"), nonmanifold="tufted", repair=True, separate_thin_parts=True)
    assert not np.array_equal(F, ice.load_mesh(project_mesh("kitten.xyz"), nonmanifold="tufted", repair=True).F)
    expected = ice.coarsen(V, F, ratio=0.1, nonmanifold="tufted", cache=False)
    assert abs(batch.load_result(out, "kitten.xyz")["P"] - expected.P).max() == 0
