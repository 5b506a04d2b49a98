"""How a mesh is refined before patching, and the uniform (global) refinement itself.

[FSLYJ] patches smooth quads.  Semi-sharp creases and corners (0 < s < 10) first take ceil(s)
steps of the sharp subdivision rules ([TLC] sec. 4), after which every sharpness is 0;
non-quad faces take one step, which turns every polygon into quads.  ``refinement_plan``
says how many steps and whether they are taken globally (``uniform_operator``: every face)
or adaptively (``adaptive.adaptive_surface_operator``: only near the features, the same
surface, patches of several levels meeting at T-junctions): siblings under one entry point,
``build.build_operator``, as OpenSubdiv's ``RefineUniform`` / ``RefineAdaptive``.  Regular quad
regions keep their surface (a step there is knot insertion).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from patching.errors import UnsupportedError
from patching.mesh.control_mesh import ControlMesh
from patching.operator.assembly import assemble
from patching.options import BuildOptions
from patching.subdivision.catmark import subdivision_operator
from patching.surface import SurfaceOperator
from patching.topology.tables import Topology
from patching.util.parallel import product

__all__ = ["refinement_plan", "semi_sharp_steps", "patched_mesh", "uniform_operator",
           "MAX_SEMI_SHARP_STEPS", "MAX_REFINED_FACES", "MAX_AUTO_GLOBAL_FACES"]

#: Most global subdivision steps (and faces after them) spent on semi-sharp features before
#: patching; beyond them the refinement is adaptive whatever ``refinement`` says.
MAX_SEMI_SHARP_STEPS = 6

MAX_REFINED_FACES = 2_000_000

#: Under refinement="auto", the most faces the global steps may make before the adaptive path
#: takes over.  Measured (benchmarks/semi_sharp.py): from about 1,000 global faces on, the
#: adaptive path always gave fewer patches (1.5x on a 96-face cube with a semi-sharp loop at
#: s = 2, 5x on a 5 x 4 torus with one crease at s = 3, 32x at s = 5); below, it saves at
#: most 2.5x (a 6-face cube at s = 2 or 3: the same 96 or 384; the torus at s = 2: 320 against
#: 152 to 272) and no time to STEP (1.8 to 2.1 s on either path, mostly OCC's fixed cost).
MAX_AUTO_GLOBAL_FACES = 1024


def semi_sharp_steps(topo: Topology) -> int:
    """ceil of the largest finite sharpness below 10 on edges and corners (0 if none)."""
    mesh = topo.mesh
    values = np.concatenate([topo.edge_sharpness, np.array(list(mesh.corners.values()), dtype=np.float64)])
    semi = values[(values > 0) & (values < 10)]
    return int(np.ceil(semi.max())) if semi.size else 0


def refinement_plan(topo: Topology, refinement: str = "auto") -> tuple[int, bool]:
    """(steps, adaptive): the subdivision steps taken before patching (semi-sharp tags, or one
    for n-gons), and whether they are taken adaptively (``adaptive``) rather than globally.

    Adaptive when the global steps would not fit (more than MAX_SEMI_SHARP_STEPS steps or
    MAX_REFINED_FACES faces), and under refinement="auto" also when they would make more than
    MAX_AUTO_GLOBAL_FACES faces, unless the adaptive path cannot go or gains nothing: a zero
    knot interval anywhere (``adaptive_operator`` refuses them), or no semi-sharp tag (the one
    step for n-gons refines every face on either path).  ValueError for another refinement."""
    mesh = topo.mesh
    semi = semi_sharp_steps(topo)
    steps = semi or (0 if mesh.is_quad_mesh else 1)
    faces = mesh.n_faces * 4**steps  # the faces after the global steps (n-gons counted as quads)
    if steps == 0:
        return 0, False
    if steps > MAX_SEMI_SHARP_STEPS or faces > MAX_REFINED_FACES:
        return steps, True
    auto = refinement == "auto" and semi > 0 and faces > MAX_AUTO_GLOBAL_FACES
    return steps, bool(auto and np.all(topo.edge_interval > 0))


def patched_mesh(mesh: ControlMesh, refinement: str = "auto") -> ControlMesh:
    """The all-quad mesh whose faces the patches of ``build_operator(mesh, refinement=...)``
    cover: the mesh itself, or after the global subdivision steps taken for semi-sharp tags
    and n-gons (its positions those steps' refinement of the control points).  Refused
    (UnsupportedError) where the refinement is adaptive: there patches of several levels
    cover the faces."""
    refinement = BuildOptions(refinement=refinement).refinement
    steps, adaptive = refinement_plan(Topology(mesh), refinement)
    if adaptive:
        raise UnsupportedError(f"{mesh.name} is refined adaptively: its patches cover faces of several levels", mesh.name)
    points = mesh.vertices
    for _ in range(steps):
        step, mesh = subdivision_operator(mesh, rules="seed", crease_method="uniform")
        points = step @ points
    return mesh.with_positions(points) if steps else mesh


def uniform_operator(mesh: ControlMesh, steps: int, options: BuildOptions) -> SurfaceOperator:
    """M of ``steps`` global subdivision steps (``subdivision.catmark``, [TLC]'s rules) then
    the patches of the refined all-quad mesh: M_refined @ S_steps ... S_1, acting on the
    original control points."""
    composed = sp.identity(mesh.n_vertices, format="csr")
    refined = mesh
    for _ in range(steps):
        step, refined = subdivision_operator(refined, rules="seed", crease_method="uniform")
        composed = (step @ composed).tocsr()
    inner = assemble(refined, Topology(refined), options)
    return SurfaceOperator(product(inner.matrix, composed), inner.groups, inner.topology, mesh.name)

