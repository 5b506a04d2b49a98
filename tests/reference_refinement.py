"""References for refined grids and discs, shared by the subdivision tests: OpenCASCADE's own
knot insertion (Boehm) on a periodic bicubic B-spline, the child ids of a refined grid or of an
EP's 1-ring, and a polar disc around one vertex of any valence with chosen spoke intervals."""

from __future__ import annotations

import numpy as np

from patching.mesh.control_mesh import from_arrays


def occ_periodic_bicubic(grid, du, dv):
    """OCC's periodic bicubic B-spline of an (m, n, 3) torus grid with knot intervals du (m,),
    dv (n,) (docs/knots.md mapping: pole (k, l) is grid point (k - 2, l - 2)); returns it with
    its u and v knot values."""
    from OCP.Geom import Geom_BSplineSurface
    from OCP.gp import gp_Pnt
    from export.ocp_compat import TColgp_Array2OfPnt
    from export.ocp_compat import TColStd_Array1OfInteger, TColStd_Array1OfReal

    m, n, _ = grid.shape
    poles = TColgp_Array2OfPnt(1, m, 1, n)
    for k in range(1, m + 1):
        for l in range(1, n + 1):
            poles.SetValue(k, l, gp_Pnt(*map(float, grid[(k - 2) % m, (l - 2) % n])))

    def knots(d):
        values = np.concatenate([[0.0], np.cumsum(d)])
        kk, mm = TColStd_Array1OfReal(1, values.size), TColStd_Array1OfInteger(1, values.size)
        for i, v in enumerate(values):
            kk.SetValue(i + 1, float(v))
            mm.SetValue(i + 1, 1)
        return kk, mm, values

    uk, um, uval = knots(du)
    vk, vm, vval = knots(dv)
    return Geom_BSplineSurface(poles, uk, vk, um, vm, 3, 3, True, True), uval, vval


def occ_refined_poles(grid, du, dv):
    """Poles of OCC's periodic bicubic B-spline (docs/knots.md mapping) after inserting the midpoint
    of every knot interval with InsertUKnot / InsertVKnot."""
    m, n, _ = grid.shape
    surf, uval, vval = occ_periodic_bicubic(grid, du, dv)
    for u in (uval[:-1] + uval[1:]) / 2:
        surf.InsertUKnot(float(u), 1, 1e-12)
    for v in (vval[:-1] + vval[1:]) / 2:
        surf.InsertVKnot(float(v), 1, 1e-12)
    nu, nv = surf.NbUPoles(), surf.NbVPoles()
    assert (nu, nv) == (2 * m, 2 * n)
    out = np.empty((nu, nv, 3))
    for k in range(1, nu + 1):
        for l in range(1, nv + 1):
            p = surf.Pole(k, l)
            out[(k - 2) % nu, (l - 2) % nv] = p.X(), p.Y(), p.Z()
    return out


def refined_ids(mesh, vid, fid):
    """Child ids of a refined grid.  vid (m, n): parent vertex of grid point (a, b); fid (m, n):
    parent face with corners (a, b), (a+1, b), (a+1, b+1), (a, b+1).  Returns the child vertex
    ids (2m, 2n): [2a, 2b] vertex point, [2a+1, 2b] edge point of (a, b)-(a+1, b), [2a, 2b+1]
    of (a, b)-(a, b+1), [2a+1, 2b+1] face point; and the child face ids (2m, 2n) in the same
    convention (child face h sits at the corner origin(h) of its parent face)."""
    from patching.topology.tables import Topology

    t = Topology(mesh)
    nf, ne = mesh.n_faces, t.n_edges
    m, n = vid.shape
    V = np.empty((2 * m, 2 * n), np.int64)
    Fc = np.empty((2 * m, 2 * n), np.int64)
    for a in range(m):
        for b in range(n):
            A, B = (a + 1) % m, (b + 1) % n
            V[2 * a, 2 * b] = nf + ne + vid[a, b]
            V[2 * a + 1, 2 * b] = nf + t.edge_id(int(vid[a, b]), int(vid[A, b]))
            V[2 * a, 2 * b + 1] = nf + t.edge_id(int(vid[a, b]), int(vid[a, B]))
            f = int(fid[a, b])
            V[2 * a + 1, 2 * b + 1] = f
            corners = [vid[a, b], vid[A, b], vid[A, B], vid[a, B]]
            cells = [(2 * a, 2 * b), (2 * a + 1, 2 * b), (2 * a + 1, 2 * b + 1), (2 * a, 2 * b + 1)]
            for h in range(mesh.face_offsets[f], mesh.face_offsets[f + 1]):
                Fc[cells[corners.index(mesh.face_vertices[h])]] = h
    return V, Fc


def polar_disk(n: int, rings: int = 3, spoke_intervals=None, seed: int = 0, outer: str = "random"):
    """An open disk of n sectors of rings x rings quads around one vertex of valence n.

    Sector i has grid points (p, q), 0 <= p, q <= rings, (0, 0) the centre, (p, 0) on spoke i,
    (0, q) on spoke i+1 (= sector i+1's (q, 0)).  spoke_intervals[i] goes on the strip of the
    spoke edge (0,0)-(1,0) of sector i; the other strips get random intervals in [1, 3]
    (outer="random") or the interval of their spoke (outer="spoke").
    """
    rng = np.random.default_rng(seed)
    ids = {}
    verts = [(0.0, 0.0, 0.0)]

    def vid(i, p, q):
        i %= n
        if p == 0 and q == 0:
            return 0
        if q == 0:
            key = ("spoke", i, p)
        elif p == 0:
            key = ("spoke", (i + 1) % n, q)
        else:
            key = ("in", i, p, q)
        if key not in ids:
            ids[key] = len(verts)
            a0, a1 = 2 * np.pi * i / n, 2 * np.pi * (i + 1) / n
            x = p * np.array([np.cos(a0), np.sin(a0)]) + q * np.array([np.cos(a1), np.sin(a1)])
            verts.append((x[0], x[1], 0.3 * np.sin(p + 2 * q) + 0.1 * rng.normal()))
        return ids[key]

    faces = []
    for i in range(n):
        for p in range(rings):
            for q in range(rings):
                faces.append([vid(i, p, q), vid(i, p + 1, q), vid(i, p + 1, q + 1), vid(i, p, q + 1)])
    intervals = {}
    for i in range(n):
        for p in range(rings):
            if spoke_intervals is not None and (p == 0 or outer == "spoke"):
                d = spoke_intervals[i]
            else:
                d = rng.uniform(1, 3)
            intervals[(vid(i, p, 0), vid(i, p + 1, 0))] = float(d)
    return from_arrays(np.array(verts), faces, intervals=intervals)


def ring_ids(mesh, v):
    """[V, E_0.., F_0..] of vertex v (eigen_polyhedron's order) and the child ids of the same
    points after one step."""
    from patching.topology.tables import Topology

    t = Topology(mesh)
    ring = t.one_ring(v)
    parent = np.concatenate([[v], t.dest[ring], t.dest[t.next[ring]]])
    child = np.concatenate([[mesh.n_faces + t.n_edges + v], mesh.n_faces + t.edge_of[ring], t.face[ring]])
    return parent, child, t.halfedge_interval[ring]
