"""Builds on a real Dask cluster (``nupatch build --dask``): a scheduler and two workers started
as processes on 127.0.0.1, no mocks.  The outputs equal a local ``-j 2`` build byte for byte
apart from the STEP header's time stamp, and a worker killed mid-batch loses no mesh."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed")

from export import write_obj  # noqa: E402
from export.pipeline import BuildJob  # noqa: E402
from patching.mesh.primitives import torus_grid  # noqa: E402
from tests.conftest import NUPATCH, REPO  # noqa: E402

pytestmark = pytest.mark.slow

DASK = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
WORKER = [sys.executable, "-m", "distributed.cli.dask_worker"]


def stamp_free(data: bytes) -> bytes:
    """A STEP file without its time stamp (FILE_NAME's second argument, an ISO date)."""
    return re.sub(rb"'\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d'", b"'TIME'", data)


@pytest.fixture
def cluster(tmp_path):
    """A scheduler and two single-threaded workers without nannies (a killed worker stays
    dead), all on 127.0.0.1; yields (address, worker processes)."""
    env = dict(os.environ, PYTHONPATH=str(REPO))
    scheduler_file = tmp_path / "scheduler.json"
    procs = [subprocess.Popen([*DASK, "--host", "127.0.0.1", "--port", "0", "--no-dashboard", "--scheduler-file", str(scheduler_file)],
                              env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        deadline = time.monotonic() + 120
        while not scheduler_file.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        import json

        address = json.loads(scheduler_file.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        workers = [subprocess.Popen([*WORKER, address, "--nthreads", "1", "--no-nanny", "--no-dashboard", "--host", "127.0.0.1"],
                                    env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for _ in range(2)]
        procs += workers
        from distributed import Client

        with Client(address, timeout="60s") as client:
            client.wait_for_workers(2, timeout=120)
        yield address, workers
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
            p.wait(timeout=30)


def meshes(tmp_path: Path, count: int = 8) -> list[Path]:
    """Small closed tori of several sizes (distinct outputs), one of them non-uniform."""
    paths = []
    for k in range(count):
        mesh = torus_grid(4 + k % 3, 4 + k // 3, name=f"torus{k}")
        path = tmp_path / f"torus{k}.obj"
        write_obj(mesh, path)
        paths.append(path)
    return paths


def test_a_batch_on_dask_equals_the_local_parallel_build(tmp_path, cluster):
    address, _ = cluster
    paths = meshes(tmp_path)
    local, remote = tmp_path / "local", tmp_path / "remote"
    local.mkdir(), remote.mkdir()
    env = dict(os.environ, PYTHONPATH=str(REPO))
    run = lambda *a: subprocess.run([*NUPATCH, "build", *map(str, paths), *a], capture_output=True, text=True, env=env, timeout=900)  # noqa: E731
    a = run("-o", str(local), "-j", "2")
    b = run("-o", str(remote), "--dask", address)
    assert a.returncode == 0 and b.returncode == 0, (a.stderr, b.stderr)
    assert len(b.stderr.strip().splitlines()) == len(paths)  # one line a mesh, no Dask noise
    for path in paths:
        mine, theirs = (d / (path.stem + ".step") for d in (local, remote))
        assert stamp_free(mine.read_bytes()) == stamp_free(theirs.read_bytes())
    assert not list(remote.glob(".*tmp*"))


def test_a_worker_killed_mid_batch_loses_no_mesh(tmp_path, cluster):
    """The first result kills one worker (SIGKILL, no nanny to restart it); the scheduler runs
    its tasks again on the other, and every mesh is written, equal to its local build."""
    from export.dask_batch import build_on_dask
    from export.pipeline import run_build

    address, workers = cluster
    paths = meshes(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    jobs = [BuildJob(str(p), str(out / (p.stem + ".step")), "step") for p in paths]
    killed = []

    def report(result):
        if not killed:
            workers[0].send_signal(signal.SIGKILL)
            killed.append(result.job.mesh)

    results = build_on_dask(jobs, address, report)
    assert killed and workers[0].wait(timeout=30) == -signal.SIGKILL
    assert sorted(r.job.out for r in results) == sorted(j.out for j in jobs)
    assert all(r.status == "ok" for r in results), [r.message for r in results]
    (tmp_path / "reference").mkdir()
    for job in jobs:  # the same base name: the STEP header carries it
        reference = BuildJob(job.mesh, str(tmp_path / "reference" / Path(job.out).name), "step")
        run_build(reference)
        assert stamp_free(Path(job.out).read_bytes()) == stamp_free(Path(reference.out).read_bytes())


def test_no_scheduler_is_one_line_and_no_file(tmp_path, run_cli):
    (path,) = meshes(tmp_path, 1)
    result = run_cli("build", path, "-o", tmp_path / "x.step", "--dask", "tcp://127.0.0.1:9")
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and "no Dask scheduler answers at tcp://127.0.0.1:9" in result.stderr
    assert not (tmp_path / "x.step").exists()
