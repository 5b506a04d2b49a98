"""One entry point for M: options validated once, the input checked once, then the uniform or
the adaptive refinement (siblings, as OpenSubdiv's ``RefineUniform`` / ``RefineAdaptive``
under one ``TopologyRefiner``), or the mesh itself when it needs none."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from patching.errors import MeshError, UnsupportedError
from patching.mesh.control_mesh import ControlMesh
from patching.operator.adaptive import adaptive_surface_operator
from patching.operator.assembly import assemble
from patching.operator.refinement import refinement_plan, uniform_operator
from patching.operator.refusals import refuse_input
from patching.options import BuildOptions
from patching.rules.crease import INFINITE, child_edge_sharpness
from patching.surface import BezierSurface, SurfaceOperator
from patching.topology.tables import Topology
from patching.util.blas import one_blas_thread

__all__ = ["build_operator", "build"]


@one_blas_thread
def build_operator(
    mesh: ControlMesh,
    options: BuildOptions | None = None,
    *,
    topology: Topology | None = None,
    force_extraordinary: Sequence[int] = (),
    angles: str | None = None,
    anchors: str | None = None,
    interior: str | None = None,
    g1_solve: str | None = None,
    refinement: str | None = None,
    method: str | None = None,
    eigen_angles: str | None = None,
) -> SurfaceOperator:
    """M for a polygon mesh with knot intervals and tags: coefficients = M @ control points.

    Bicubic patches on regular faces, G1 bi-quintic patches on faces touching extraordinary
    points ([FSLYJ] sec. 3), sharp features as in [FSLYJ] sec. 4.2.  Semi-sharp tags and
    non-quad faces are refined first (``refinement``), globally or adaptively, and M includes
    those steps.  ``options`` (``BuildOptions``) or its fields as keywords choose the angle
    configuration, anchors (and the eigen-polyhedron angles that place them), interior rule, G1
    solve, refinement and method (``"t-spline"``: the [SSEL13] baseline,
    ``extraordinary.t_spline``); ``topology``: the mesh's
    Topology if already built; ``force_extraordinary``: interior vertices patched as EPs
    whatever their valence.  OptionError for an unknown option value.
    """
    if not isinstance(mesh, ControlMesh):
        raise MeshError(f"mesh must be a ControlMesh (read_mesh or from_arrays), not {type(mesh).__name__}", "mesh")
    if topology is not None and not isinstance(topology, Topology):
        raise MeshError(f"topology must be a Topology of the mesh, not {type(topology).__name__}", "topology")
    options = BuildOptions.of(
        options, angles=angles, anchors=anchors, interior=interior, g1_solve=g1_solve, refinement=refinement,
        method=method, eigen_angles=eigen_angles,
    )
    if mesh.triangle_subdivision == "smooth" and (mesh.face_sizes == 3).any():
        # Refined with rules "seed", whose triangles are Catmull-Clark's: the surface would
        # silently differ from OpenSubdiv's TRI_SUB_SMOOTH limit surface.
        raise UnsupportedError(
            "smooth triangles (t smoothtriangles, OpenSubdiv's TRI_SUB_SMOOTH) are a rule of "
            "'nupatch subdivide --rules opensubdiv' only: build refines triangles by Catmull-Clark (remove the tag)",
            mesh.where("tag", "smoothtriangles"),
        )
    topo = topology or Topology(mesh)
    _refuse_chaikin(mesh, topo)
    # Tears are judged on the user's mesh, before any refinement: refining a zero strip
    # inserts its knot again (two halves of interval 0), so the refined mesh shows runs of
    # 2^k zero strips where the surface is the input's.
    refuse_input(topo)
    steps, adaptive = refinement_plan(topo, options.refinement)
    if (steps or adaptive) and len(force_extraordinary):
        raise UnsupportedError("force_extraordinary applies to meshes that need no refinement", mesh.name)
    if adaptive:
        return adaptive_surface_operator(mesh, options)
    if steps:
        return uniform_operator(mesh, steps, options)
    return assemble(mesh, topo, options, force_extraordinary)


def build(
    mesh: ControlMesh, options: BuildOptions | None = None, *, operator: SurfaceOperator | None = None, **option_fields: str
) -> BezierSurface:
    """The patched surface of a mesh: ``build_operator(mesh, options).evaluate(mesh.vertices)``
    (``refinement="global"`` for ``export.pack``, which needs the patches of one mesh).
    ``operator``: that M, already built for this mesh's topology, intervals, tags and these
    options (by ``build_operator``, or kept from an earlier build: ``operator.archive``).

    MeshError when no face gives a patch (holes, interpolateboundary 0, zero intervals): an
    empty surface is no solid or shell, and nothing the exporters could write."""
    if operator is None:
        operator = build_operator(mesh, BuildOptions.of(options, **option_fields))
    surface = operator.evaluate(mesh.vertices)
    if surface.n_patches == 0:
        causes = [f"{len(mesh.holes)} of {mesh.n_faces} faces are holes"] if mesh.holes else []
        if mesh.interpolate_boundary == 0:
            causes.append("interpolateboundary 0 drops every face at the open boundary")
        if any(d == 0.0 for d in mesh.intervals.values()):
            causes.append("zero knot intervals leave faces of no parametric area")
        raise MeshError(f"no face gives a patch, the surface is empty ({'; '.join(causes) or 'no face has a patch'})", mesh.name)
    return surface


def _refuse_chaikin(mesh: ControlMesh, topo: Topology) -> None:
    """Build refines semi-sharp tags with uniform creasing (``refinement``, ``adaptive``: rules
    "seed"), so a mesh tagged ``crease_method="chaikin"`` is refused where Chaikin's first step
    would give another sharpness: at a vertex with two or more semi-sharp edges of different
    sharpness (``patching.rules.crease``).  Where the first step agrees, every later one does
    too (the semi-sharp edges at each vertex stay equal, all dropping by 1), so the surface is
    the same and the build goes on."""
    if mesh.crease_method != "chaikin":
        return
    es = topo.edge_sharpness.copy()
    es[topo.edge_is_boundary] = np.inf  # boundary edges are infinitely sharp in every mode
    chaikin = child_edge_sharpness(np.minimum(es, INFINITE), topo.edges, topo.n_vertices, "chaikin")
    uniform = child_edge_sharpness(np.minimum(es, INFINITE), topo.edges, topo.n_vertices, "uniform")
    if not np.allclose(chaikin, uniform, rtol=0.0, atol=1e-12):  # rounding in Chaikin's mean of equal values
        raise UnsupportedError(
            "chaikin creasing (t creasemethod, OpenSubdiv's CREASE_CHAIKIN) is a rule of 'nupatch subdivide "
            "--rules opensubdiv' only: build decays semi-sharp creases uniformly (remove the tag)",
            mesh.locations.get(("tag", "creasemethod"), "crease_method"),
        )
