"""Regenerate the parametric sample meshes in models/ (run from the repo root):

    .venv/bin/python models/generate.py
"""

from pathlib import Path

from export import write_obj
from patching.mesh.primitives import open_grid, torus_grid

HERE = Path(__file__).parent

# A 12 x 8 torus whose strips carry intervals from 0.5 to 6 (max/min 12), one of them a
# double knot (0: C1 ring) so that the demo exercises multiple knots too.
write_obj(
    torus_grid(12, 8, [1, 2, 4, 6, 3, 1, 0.5, 1, 2, 0, 1.5, 1], [1, 3, 1, 0.5, 2, 1, 4, 1], name="torus_nonuniform"),
    HERE / "torus_nonuniform.obj",
    comment="nupatch sample: closed 12 x 8 torus grid with non-uniform knot intervals (one zero strip)",
)
# An open 9 x 7 grid whose outermost strips carry 0: a clamped bicubic NURBS patch.
write_obj(
    open_grid(9, 7, [0, 1, 2, 1, 1, 3, 1, 0], [0, 1, 1, 2, 1, 0], name="clamped_grid"),
    HERE / "clamped_grid.obj",
    comment="nupatch sample: open 9 x 7 grid, zero outer strips (clamped NURBS), non-uniform inside",
)


def polycube_with_tight_edges(voxels, divisions, name, edge_interval):
    """A polycube whose outermost strips along each axis carry a small interval: the knots
    crowd towards the box edges, which rounds them more tightly (a NURBS designer's trick)."""
    import numpy as np

    from patching.mesh.control_mesh import from_arrays
    from patching.mesh.primitives import polycube
    from patching.topology.tables import Topology

    mesh = polycube(voxels, divisions, name=name)
    topo = Topology(mesh)
    p = mesh.vertices[topo.edges]  # (e, 2, 3)
    axis = np.argmax(np.abs(p[:, 1] - p[:, 0]), axis=1)
    lo = np.minimum(p[np.arange(len(p)), 0, axis], p[np.arange(len(p)), 1, axis])
    hi = np.maximum(p[np.arange(len(p)), 0, axis], p[np.arange(len(p)), 1, axis])
    vmin, vmax = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    outer = np.isclose(lo, vmin[axis]) | np.isclose(hi, vmax[axis])
    intervals = {tuple(int(v) for v in topo.edges[e]): edge_interval for e in np.flatnonzero(outer)}
    faces = [list(mesh.face(f)) for f in range(mesh.n_faces)]
    return from_arrays(mesh.vertices, faces, intervals=intervals, name=name)


# An L-shaped bracket: valence-3 EPs at convex corners, valence-5 at the inner corner, knots
# crowded towards the outer edges (interval 0.3 against 1).
write_obj(
    polycube_with_tight_edges([(0, 0, 0), (1, 0, 0), (2, 0, 0), (0, 1, 0), (0, 2, 0)], 3, "l_bracket", 0.3),
    HERE / "l_bracket.obj",
    comment="nupatch sample: L-shaped polycube, EPs of valence 3 and 5, intervals 0.3 on the outer strips, 1 elsewhere",
)
# A square frame (genus 1): valence-3 and valence-5 EPs, all intervals 1 but the outer ones.
write_obj(
    polycube_with_tight_edges([(x, y, 0) for x in range(3) for y in range(3) if (x, y) != (1, 1)], 2, "square_frame", 0.5),
    HERE / "square_frame.obj",
    comment="nupatch sample: a square frame of 8 cubes (genus 1), EPs of valence 3 and 5, non-uniform intervals",
)


def sharp_top_and_sides(mesh, name: str):
    """Mark the polycube's geometric edges (where the control faces on either side are
    perpendicular) infinitely sharp, except those in the bottom plane (z = 0), which stay
    smooth and round off: a machined top with sharp rims, and vertical arrises that fade out
    into the soft base (darts at the bottom corners)."""
    import numpy as np

    from patching.mesh.control_mesh import from_arrays
    from patching.topology.tables import Topology

    topo = Topology(mesh)
    quads = mesh.quads()
    p = mesh.vertices[quads]
    normals = np.cross(p[:, 1] - p[:, 0], p[:, 3] - p[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    face_of = topo.face
    h = np.flatnonzero(topo.twin >= 0)
    bend = np.abs((normals[face_of[h]] * normals[face_of[topo.twin[h]]]).sum(1)) < 0.5
    ends = topo.origin[h], topo.dest[h]
    low = (mesh.vertices[ends[0], 2] == 0) & (mesh.vertices[ends[1], 2] == 0)
    creases = {tuple(sorted((int(a), int(b)))): np.inf for a, b in zip(ends[0][bend & ~low], ends[1][bend & ~low])}
    faces = [list(mesh.face(f)) for f in range(mesh.n_faces)]
    return from_arrays(mesh.vertices, faces, intervals=dict(mesh.intervals), creases=creases, name=name)


# A machined bracket: a plate with a notch and a square pocket through it (genus 1), sharp top
# rims and vertical edges (corners where three meet, the concave ones valence-5 EPs with a
# three-face sector, darts where the vertical edges reach the rounded bottom), knots crowded
# towards the outer edges (0.4 against 1).
write_obj(
    sharp_top_and_sides(
        polycube_with_tight_edges(
            [(x, y, 0) for x in range(4) for y in range(3) if (x, y) not in {(1, 1), (3, 2)}], 2, "machined_bracket", 0.4
        ),
        "machined_bracket",
    ),
    HERE / "machined_bracket.obj",
    comment="nupatch sample: machined bracket, sharp top rims and vertical edges, convex and concave corners, darts, intervals 0.4 / 1",
)
