"""The build pipeline that the command line and the Python API share: read a mesh, build its
surface, make the B-rep (patch by patch, or packed into multi-span faces), warn about folds,
write the file atomically.  ``build_file`` is one mesh; ``build_files`` many, in worker
processes, each result reported on its own."""

from __future__ import annotations

import os
import time
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

import patching
from patching.errors import NupatchError
from patching.options import BuildOptions

__all__ = ["BuildJob", "BuildResult", "EXACT_FORMATS", "STAGES", "build_file", "build_files", "build_one", "run_build", "warn_folds"]

#: Formats that carry the exact B-rep, so that packing applies to them.
EXACT_FORMATS = ("step", "iges", "brep")
#: Stages of one build, for progress reports.
STAGES = ("reading", "patches", "B-rep", "writing")


@dataclass(frozen=True)
class BuildJob:
    """One mesh to build and write: what a worker process receives (picklable).

    mesh, out: paths; fmt: a format of ``export.formats.FORMATS``; tolerance: the linear
    deflection of tessellated formats (None: their default); options: the build's choices;
    pack: regular regions as multi-span B-spline faces (exact formats only): True packs after
    global refinement, False never packs, None (the default) packs what the adaptive path
    builds (semi-sharp tags refined near the features: there the leaves' regular regions are
    thousands of patches of one B-spline, the file otherwise tens of MB); intervals: how
    strips without interval tags get theirs (``patching.topology.intervals``); cache: keep solved
    local configurations and whole operators on disk between builds (``export.solve_cache``,
    ``export.operator_cache``; the command line's default)."""

    mesh: str
    out: str
    fmt: str
    tolerance: float | None = None
    options: BuildOptions = field(default_factory=BuildOptions)
    pack: bool | None = None
    intervals: str = "tags"
    cache: bool = False


@dataclass(frozen=True)
class BuildResult:
    """What one job gave: status "ok", "error" (bad input) or "bug"; a one-line message; the
    NupatchWarnings raised on the way."""

    job: BuildJob
    status: str
    message: str
    notes: tuple[str, ...] = ()


def run_build(job: BuildJob, stage: Callable[[str], None] = lambda name: None) -> tuple[int, int]:
    """Read, build, make the B-rep and write one mesh; returns (faces, patches).  ``stage(name)``
    is called as each stage starts.  Raises the NupatchError family on bad input."""
    from export.operator_cache import using_operator_cache
    from export.solve_cache import using_disk_cache

    with using_disk_cache(job.cache), using_operator_cache(job.cache) as operators:
        return _run_build(job, stage, operators)


def _run_build(job: BuildJob, stage: Callable[[str], None], operators) -> tuple[int, int]:
    from export.brep import to_shape
    from export.formats import write
    from export.inputs import read_control_mesh

    stage(STAGES[0])
    mesh = read_control_mesh(job.mesh, job.intervals)
    stage(STAGES[1])
    exact = job.fmt in EXACT_FORMATS
    # --pack merges the patches of one mesh: semi-sharp tags then take the global steps while
    # they fit (``patching.operator.refinement``), not the adaptive path.
    options = BuildOptions.of(job.options, refinement="global") if job.pack and exact else job.options
    from export.operator_cache import operator_for

    surface = patching.build(mesh, options, operator=operator_for(mesh, options, operators))
    stage(STAGES[2])
    # By default the adaptive path's output is packed: its patches carry their knot spans.
    adaptive = bool(surface.groups) and all(g.spans is not None for g in surface.groups)
    pack = exact and (job.pack or (job.pack is None and adaptive))
    if pack:
        from export.pack import patch_spans, to_packed_shape

        shape, _ = to_packed_shape(surface, patch_spans(surface, mesh))
    else:
        shape = to_shape(surface)
    from export.budget import warn_many_patches

    warn_many_patches(mesh, surface)  # >50k patches from a small mesh: the tags that made them
    warn_folds(surface)  # after the B-rep: a refused surface gets its one line only
    stage(f"{STAGES[3]} {job.fmt}")
    write(surface, job.out, job.fmt, tolerance=job.tolerance, shape=shape)
    return mesh.n_faces, surface.n_patches


def build_file(
    mesh: str | os.PathLike,
    out: str | os.PathLike | None = None,
    format: str | None = None,
    *,
    options: BuildOptions | None = None,
    pack: bool | None = None,
    tolerance: float | None = None,
) -> Path:
    """Build the mesh file ``mesh`` and write it to ``out`` (default: beside it, ``.step``) in
    ``format`` (default: from the suffix), exactly as ``nupatch build`` does; returns the path.
    pack: as ``BuildJob.pack`` (None: pack the adaptive path's output)."""
    from export.atomic import check_output_path
    from export.formats import format_of

    if tolerance is not None:
        from export.tolerances import check_tolerance

        check_tolerance(tolerance)
    mesh = Path(mesh)
    out = Path(out) if out is not None else mesh.with_suffix("." + (format or "step"))
    if out.resolve() == mesh.resolve():
        raise NupatchError("the output would overwrite the input mesh", str(out))
    fmt = format_of(out, format)
    check_output_path(out)
    run_build(BuildJob(str(mesh), str(out), fmt, tolerance, options or BuildOptions(), pack))
    return out


def warn_folds(surface: patching.BezierSurface) -> None:
    """A NupatchWarning when a patch folds over itself (``evaluation.normal_turning`` below 0
    on 9 x 9 samples): G1 holds, but the surface is not what a CAD user wants, and the cure
    (finer control mesh near the EPs) is theirs to apply."""
    from patching.evaluation import normal_turning

    _, turning = normal_turning(surface, samples=9)
    folded = int((turning < 0.0).sum())
    if folded:
        warnings.warn(
            patching.NupatchWarning(
                f"{folded} of {turning.size} patches fold over themselves: next to extraordinary points the "
                "knot intervals run against the control net's spacing; one `nupatch subdivide` step of the mesh "
                "usually removes such folds"
            )
        )


def build_one(job: BuildJob) -> BuildResult:
    """Run one job and report it as a BuildResult (bad input and bugs alike); never raises."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", patching.NupatchWarning)
        try:
            start = time.perf_counter()
            faces, patches = run_build(job)
            status = "ok"
            message = f"{job.mesh}: {patches} patches from {faces} faces, wrote {job.out} ({job.fmt}) in {time.perf_counter() - start:.2f} s"
        except NupatchError as exc:
            status, message = "error", f"error: {exc}"
        except Exception as exc:  # a bug, reported on its own line like the others
            status, message = "bug", f"internal error: {type(exc).__name__}: {exc} ({job.mesh}; please report)"
    notes = tuple(str(w.message) for w in caught if issubclass(w.category, patching.NupatchWarning))
    return BuildResult(job, status, message, notes)


def build_files(jobs: Iterable[BuildJob], workers: int = 1, report: Callable[[BuildResult], None] = lambda r: None) -> list[BuildResult]:
    """Build every job, in up to ``workers`` processes; ``report`` is called with each result as
    it comes (in completion order); one failure never stops the others."""
    from concurrent.futures import as_completed

    from export.signals import worker_pool

    jobs = list(jobs)
    results = []
    if workers <= 1 or len(jobs) <= 1:
        for job in jobs:
            results.append(build_one(job))
            report(results[-1])
        return results
    with worker_pool(min(workers, len(jobs))) as pool:  # workers die with this process
        for future in as_completed([pool.submit(build_one, job) for job in jobs]):
            results.append(future.result())
            report(results[-1])
    return results
