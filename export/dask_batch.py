"""Builds on a Dask cluster (``nupatch build MESHES... --dask ADDRESS``): each task builds one
mesh on a worker into a private temporary directory and returns the file's bytes, and the
client writes them atomically where the job says, so no shared file system is needed.

A worker lost mid-task loses its result: Dask's scheduler runs the task again on another
worker (``retries`` covers tasks that raise on a worker for reasons of that worker).  A mesh's
own error (bad input, a bug) is returned as its ``BuildResult``, never raised, so one failure
neither stops the others nor is retried.  ``distributed`` is the optional extra ``[dask]``.
"""

from __future__ import annotations

import logging
import os
import tempfile
from collections.abc import Callable, Iterable
from dataclasses import replace
from pathlib import Path

from patching.errors import NupatchError, OutputError

from export.pipeline import BuildJob, BuildResult, build_one

__all__ = ["build_on_dask", "connect", "LOCAL"]

#: The address that means "a LocalCluster on this machine" (two single-threaded workers).
LOCAL = "local"
#: Tries of one task beyond the first when it raises on a worker (not for a lost worker,
#: which the scheduler reschedules by itself).
RETRIES = 2


def _import_distributed():
    try:
        import distributed
    except ImportError:
        raise NupatchError("--dask needs the distributed package: pip install 'nupatch[dask]'", "--dask") from None
    return distributed


def connect(address: str, workers: int = 2):
    """A ``distributed.Client``: of a running scheduler (``tcp://host:port``), or of a new
    LocalCluster here (``local``, ``workers`` processes of one thread).  NupatchError naming the
    address when no scheduler answers."""
    distributed = _import_distributed()
    if address == LOCAL:
        cluster = distributed.LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=logging.ERROR
        )
        return distributed.Client(cluster)
    if "://" not in address:
        raise NupatchError(f"--dask takes tcp://host:port or {LOCAL!r}, not {address!r}", "--dask")
    try:
        return distributed.Client(address, timeout="10s")
    except (OSError, TimeoutError) as exc:
        raise NupatchError(f"no Dask scheduler answers at {address} ({type(exc).__name__})", "--dask") from None


def _build_bytes(job: BuildJob) -> tuple[BuildResult, bytes | None]:
    """On a worker: build ``job`` into a private directory under the output's own file name
    (the STEP header carries it) and return the result with the file's bytes."""
    with tempfile.TemporaryDirectory(prefix="nupatch-dask-") as tmp:
        local = replace(job, out=str(Path(tmp) / Path(job.out).name))
        result = build_one(local)
        data = Path(local.out).read_bytes() if result.status == "ok" else None
    return replace(result, job=job, message=result.message.replace(local.out, job.out)), data


def build_on_dask(
    jobs: Iterable[BuildJob], address: str, report: Callable[[BuildResult], None] = lambda r: None, *, client=None
) -> list[BuildResult]:
    """Build every job on the cluster at ``address`` (or on ``client``); each file is written
    here, atomically, as its result arrives; ``report`` is called with each result in
    completion order."""
    from export.atomic import atomic_output

    distributed = _import_distributed()
    jobs = list(jobs)
    own = client is None
    client = client or connect(address)
    results = []
    try:
        futures = [client.submit(_build_bytes, job, key=f"nupatch-{k}-{os.path.basename(job.out)}", retries=RETRIES, pure=False)
                   for k, job in enumerate(jobs)]
        for future in distributed.as_completed(futures):
            result, data = future.result()
            if data is not None:
                try:
                    with atomic_output(result.job.out) as tmp:
                        tmp.write_bytes(data)
                except OutputError as exc:
                    result = replace(result, status="error", message=f"error: {exc}")
            results.append(result)
            report(result)
    finally:
        if own:
            cluster = getattr(client, "cluster", None)
            client.close()
            if cluster is not None:
                cluster.close()
    return results
