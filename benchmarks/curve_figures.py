"""[KSD] Figs. 1-4 and 10-15 as PNGs under docs/figures/, and the time of the curve operators.

    PYTHONPATH=. python benchmarks/curve_figures.py [--out docs/figures] [--shapes DIR]

Figs. 10-15 (surfaces, [KSD] sec. 5) are described in docs/curves.md, with what differs from
the paper's pictures.

Fig. 1: a letter G of the quintic crease scheme T_5 (sharp vertices green, the polygon after
one step grey).  Fig. 2: a quintic with three semi-sharp vertices at s = 0, 1, 2, 3, inf (grey
to red) and the three basis functions at the middle crease for each s.  Fig. 3: quintic end
conditions: the T_5 end (blue) against the smooth curve (grey), the tangent at P_0 and the
displayed point P~1 = (10 P_1 + P_2) / 11 ([KSD] sec. 3.2.1); the red curve of [KSD14b] (29)
is not reproduced.  Fig. 4: the modified quintic T~5 (eq. (7)) at the same sharpness values,
by refinement (it has no exact B-spline form).  Then a table: polygon size, degree, seconds for
``Curve.limit()`` (exact) and ``refine(5)``.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.interpolate import BSpline  # noqa: E402

from patching.curves.creases import modified_quintic_step  # noqa: E402
from patching.curves.curve import Curve  # noqa: E402

SHARPNESS = [0, 1, 2, 3, math.inf]
COLOURS = ["0.6", "#f4a582", "#d6604d", "#b2182b", "#67001f"]


def _plot_curve(ax, curve: Curve, **kw):
    lim = curve.limit()
    t = np.linspace(*lim.domain, 2000)
    p = lim.evaluate(t)
    ax.plot(p[:, 0], p[:, 1], **kw)


def figure_1(out: Path) -> None:
    P = np.array([[4.2, 4.3], [3.2, 5], [1, 5], [0, 3.8], [0, 1.2], [1, 0], [3.2, 0], [4.2, 0.9], [4.2, 2.3],
                  [2.6, 2.3], [2.6, 1.7]])
    sharp = {0: math.inf, 7: math.inf, 8: math.inf, 9: math.inf, 10: math.inf}
    c = Curve(P, 5, corners=sharp)
    fig, ax = plt.subplots(figsize=(5, 5.5))
    ax.plot(P[:, 0], P[:, 1], "o-", color="0.3", lw=0.8, ms=4)
    r = c.refine(1).points
    ax.plot(r[:, 0], r[:, 1], ".-", color="0.7", lw=0.6, ms=3)
    _plot_curve(ax, c, color="k", lw=2)
    idx = sorted(sharp)
    ax.plot(P[idx, 0], P[idx, 1], "o", color="green", ms=7)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.set_title("[KSD] Fig. 1: letter G, quintic T_5 (sharp: green)")
    fig.savefig(out / "curves_fig1_letter_g.png", dpi=120, bbox_inches="tight")
    plt.close(fig)


def _zigzag() -> np.ndarray:
    x = np.arange(11.0)
    y = np.array([0, 2, 0, 2, 0, 2, 0, 2, 0, 2, 0], dtype=float)
    return np.c_[x, y]


def figure_2(out: Path) -> None:
    P = _zigzag()
    n = len(P)
    inner = [3, 5, 7]
    fig, (ax, bx) = plt.subplots(2, 1, figsize=(8, 6), gridspec_kw={"height_ratios": [2, 1]})
    ax.plot(P[:, 0], P[:, 1], "o-", color="0.3", lw=0.8, ms=4)
    ax.plot(P[inner, 0], P[inner, 1], "o", color="green", ms=7)
    for s, col in zip(SHARPNESS, COLOURS):
        corners = {0: math.inf, n - 1: math.inf, **{v: s for v in inner if s}}
        c = Curve(P, 5, corners=corners)
        _plot_curve(ax, c, color=col, lw=1.5, label=f"s = {s}")
        knots, W, _ = c.limit_operator()
        t = np.linspace(3.0, 7.0, 800)
        for j in (4, 5, 6):
            bx.plot(t, BSpline(knots, W.toarray()[:, j], 5)(t), color=col, lw=1.2)
    ax.legend(loc="upper right", fontsize=8)
    ax.set_aspect("equal")
    ax.set_title("[KSD] Fig. 2: quintic T_5, semi-sharp vertices 3, 5, 7")
    bx.set_title("basis functions of P_4, P_5, P_6 (crease at 5)", fontsize=9)
    fig.tight_layout()
    fig.savefig(out / "curves_fig2_semi_sharp_quintic.png", dpi=120)
    plt.close(fig)


def figure_3(out: Path) -> None:
    P = np.array([[0, 0], [1, 2], [3, 2.5], [5, 1], [6, 3], [8, 3], [9, 1.0]])
    n = len(P)
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(P[:, 0], P[:, 1], "o-", color="0.3", lw=0.8, ms=4)
    _plot_curve(ax, Curve(P, 5), color="0.6", lw=1.5, label="smooth (uniform, n - d spans)")
    c = Curve(P, 5, corners={0: math.inf, n - 1: math.inf})
    _plot_curve(ax, c, color="tab:blue", lw=1.8, label="T_5 end conditions")
    # c'(0) = (-11 P0 + 10 P1 + P2) / 12 ([KSD] eq. (6)): compare with the exact limit
    lim = c.limit()
    d1 = BSpline(lim.knots, lim.poles, 5).derivative()(0.0)
    expected = (-11 * P[0] + 10 * P[1] + P[2]) / 12
    assert np.allclose(d1, expected, atol=1e-12), (d1, expected)
    tan = P[0] + np.outer([0, 2.0], d1 / np.linalg.norm(d1))
    ax.plot(tan[:, 0], tan[:, 1], "--", color="tab:blue", lw=1)
    shown = (10 * P[1] + P[2]) / 11
    ax.plot(*shown, "s", color="tab:blue", ms=7, label="P~1 = (10 P1 + P2)/11")
    ax.legend(fontsize=8)
    ax.set_aspect("equal")
    ax.set_title("[KSD] Fig. 3: quintic end conditions, tangent at P_0 through P~1")
    fig.savefig(out / "curves_fig3_quintic_end.png", dpi=120, bbox_inches="tight")
    plt.close(fig)


def figure_4(out: Path) -> None:
    P = _zigzag()
    n = len(P)
    inner = [3, 5, 7]
    fig, ax = plt.subplots(figsize=(8, 4))
    ax.plot(P[:, 0], P[:, 1], "o-", color="0.3", lw=0.8, ms=4)
    ax.plot(P[inner, 0], P[inner, 1], "o", color="green", ms=7)
    for s, col in zip(SHARPNESS, COLOURS):
        sharp = np.zeros(n)
        sharp[inner] = s
        Q = P
        for _ in range(7):
            A, sharp = modified_quintic_step(len(Q), False, sharp)
            Q = A @ Q
        ax.plot(Q[:, 0], Q[:, 1], color=col, lw=1.5, label=f"s = {s}")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_aspect("equal")
    ax.set_title("[KSD] Fig. 4: modified quintic T~5 (7 refinement steps)")
    fig.savefig(out / "curves_fig4_modified_quintic.png", dpi=120, bbox_inches="tight")
    plt.close(fig)


# ------------------------------------------------------------------ surfaces ([KSD] sec. 5)
def _save(fig, path: Path) -> None:
    from export.atomic import atomic_output

    with atomic_output(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)


def _height_field(kind: str, s: float, degree: int = 3, n: int = 9, steps: int = 4):
    """The basis function of one vector of ``kind`` (U, V or X) at the grid centre as a
    height field over the refined planar grid (tensor_operators, P = 0, W = 1)."""
    from patching.curves.surface_vectors import tensor_operators

    A, C, (mu, mv) = tensor_operators((n, n), (degree, degree), (False, False), [(kind, n // 2, n // 2, s)], steps)
    a, b = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float), indexing="ij")
    xy = A @ np.c_[a.ravel(), b.ravel()]
    z = np.asarray(C.toarray()[:, 0])
    return xy[:, 0].reshape(mu, mv), xy[:, 1].reshape(mu, mv), z.reshape(mu, mv)


def figure_10(out: Path) -> None:
    """[KSD] Fig. 10: crease basis functions at several sharpness values; top N^(u) N^(v)
    (an X vector), bottom N^(u) B(v) (a V vector); bicubic, 4 steps."""
    values = [0.5, 1, 2, math.inf]
    fig = plt.figure(figsize=(12, 6))
    for r, kind in enumerate(("X", "V")):
        for c, s in enumerate(values):
            ax = fig.add_subplot(2, 4, 4 * r + c + 1, projection="3d")
            x, y, z = _height_field(kind, s, n=7)
            keep = (np.abs(x[:, 0] - 3) <= 1.6), (np.abs(y[0] - 3) <= 1.6)  # the support, +- 1 span
            x, y, z = (a[np.ix_(*keep)] for a in (x, y, z))
            ax.plot_surface(x, y, z, cmap="viridis", linewidth=0.2, edgecolor="0.3", antialiased=True, rcount=60, ccount=60)
            ax.view_init(30, -55)
            ax.set_zlim(0, 1)
            ax.set_title(f"{'N^(u) N^(v)' if kind == 'X' else 'N^(u) B(v)'}, s = {s}", fontsize=9)
            ax.set_axis_off()
    fig.suptitle("[KSD] Fig. 10: crease basis functions of control vectors at several sharpness values")
    _save(fig, out / "curves_fig10_crease_basis.png")


def figure_11(out: Path) -> None:
    """[KSD] Fig. 11 (right): a biquintic surface with a vanishing crease from a vector of
    type B(u) N^(v) (a U vector); the left (a biquintic cuboid with creases) needs biquintic
    subdivision on general meshes, which is not built."""
    from patching.curves.surface_vectors import tensor_operators

    n = 13
    A, C, (mu, mv) = tensor_operators((n, n), (5, 5), (False, False), [("U", n // 2, n // 2, math.inf)], 4)
    a, b = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float), indexing="ij")
    P = np.c_[a.ravel(), b.ravel(), 0.15 * np.sin(a.ravel() / 3.0)]
    S = A @ P + C @ np.array([[0.0, 0.0, 0.5]])
    fig = plt.figure(figsize=(7, 5))
    ax = fig.add_subplot(projection="3d")
    X, Y, Z = (S[:, k].reshape(mu, mv) for k in range(3))
    from matplotlib.colors import LightSource

    ax.plot_surface(X, Y, Z, color="0.85", linewidth=0, rcount=160, ccount=160, shade=True,
                    lightsource=LightSource(azdeg=20, altdeg=35))
    ax.set_box_aspect((1, 1, 0.35))
    ax.view_init(50, -30)
    ax.set_axis_off()
    ax.set_title("[KSD] Fig. 11 (right): biquintic, a vanishing crease from one B(u) N^(v) vector")
    _save(fig, out / "curves_fig11_biquintic_vanishing_crease.png")


def figure_12(out: Path) -> None:
    """[KSD] Fig. 12: the bicubic vector stencils, read off the operator (x 64): where one line
    vector goes (points), its children (vectors), and an X vector's."""
    from patching.curves.surface_vectors import CROSS, LINE, SurfaceVector, vector_step
    from patching.mesh.primitives import torus_grid

    m = 8
    mesh = torus_grid(m, m)
    v, w = 4 * m + 4, 5 * m + 4
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.5))
    panels = [
        ("line vector: contributions to new points", SurfaceVector(LINE, v, w, math.inf), "C"),
        ("line vector: new vectors", SurfaceVector(LINE, v, w, math.inf), "H"),
        ("cross (X) vector: points (red), vectors (blue)", SurfaceVector(CROSS, v, -1, math.inf), "CH"),
    ]
    for ax, (title, vec, what) in zip(axes, panels):
        A, C, H, child, kids = vector_step(mesh, [vec])
        # fine grid coordinates: child vertex positions on the torus parameter grid
        uv = _torus_uv(mesh, m)
        fine = A @ uv
        for f in child.face_vertices.reshape(-1, 4):
            q = fine[np.r_[f, f[0]]]
            if np.abs(np.diff(q, axis=0)).max() < 1.5:
                ax.plot(q[:, 0], q[:, 1], color="0.85", lw=0.6)
        if "C" in what:
            for i in np.flatnonzero(C.toarray()[:, 0]):
                ax.text(fine[i, 0], fine[i, 1] + 0.12, f"{64 * C[i, 0]:g}", color="tab:red", ha="center", va="center", fontsize=10)
        if "H" in what:
            for k, kid in enumerate(kids):
                if what == "CH":  # all at v: one line each
                    d = fine[kid.toward] - fine[kid.vertex] if kid.kind == LINE else None
                    name = "X" if d is None else ("line along u" if abs(d[0]) > abs(d[1]) else "line along v")
                    ax.text(fine[kid.vertex, 0], fine[kid.vertex, 1] - 0.15 * (k + 1), f"{64 * H[k, 0]:g} ({name})",
                            color="tab:blue", ha="center", va="center", fontsize=9)
                else:
                    ax.text(fine[kid.vertex, 0], fine[kid.vertex, 1] - 0.12, f"{64 * H[k, 0]:g}",
                            color="tab:blue", ha="center", va="center", fontsize=10)
        ax.plot(*fine[child.n_vertices - mesh.n_vertices + v], "ko", ms=4)
        ax.set_xlim(2.6, 5.4)
        ax.set_ylim(2.6, 5.4)
        ax.set_aspect("equal")
        ax.set_title(title, fontsize=9)
        ax.axis("off")
    fig.suptitle("[KSD] Fig. 12: bicubic control-vector stencils (x 1/64), read off the operator (black: the vector's vertex; the line vector's crease runs along u, left to right)")
    _save(fig, out / "curves_fig12_stencils.png")


def _torus_uv(mesh, m):
    ids = np.arange(mesh.n_vertices)
    return np.c_[ids // m, ids % m].astype(float)


def _limit_points(mesh) -> np.ndarray:
    """Catmull-Clark limit points of the valence-4 vertices ([1 4 1; 4 16 4; 1 4 1] / 36); others NaN."""
    from patching.topology.tables import Topology

    topo = Topology(mesh)
    out = np.full_like(mesh.vertices, np.nan)
    for v in np.flatnonzero(topo.valence == 4):
        ring = topo.one_ring(int(v))
        if len(ring) != 4:
            continue
        edge = mesh.vertices[topo.dest[ring]].sum(axis=0)
        diag = mesh.vertices[topo.origin[topo.next[topo.next[ring]]]].sum(axis=0)
        out[v] = (16 * mesh.vertices[v] + 4 * edge + diag) / 36
    return out


def _walk_line(mesh, v: int, w: int, length: int) -> list[tuple[int, int]]:
    """(vertex, next) pairs along the grid line from v through w, while the vertices are regular."""
    from patching.curves.surface_vectors import check_vectors, LINE, SurfaceVector
    from patching.topology.tables import Topology

    topo = Topology(mesh)
    out = []
    prev, cur = v, w
    out.append((v, w))
    for _ in range(length):
        try:
            check_vectors(mesh, [SurfaceVector(LINE, cur, prev, math.inf)], topo)
        except Exception:
            break
        ring = topo.one_ring(cur)
        dest = topo.dest[ring]
        k = int(np.flatnonzero(dest == prev)[0])
        nxt = int(dest[(k + 2) % 4])
        out.append((cur, nxt))
        if nxt == v:  # a closed grid loop: once round
            break
        prev, cur = cur, nxt
    return out


def _draw_mesh(ax, mesh, values=None, cmap="coolwarm", vmax=None):
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    quads = mesh.vertices[mesh.face_vertices.reshape(-1, 4)]
    n = np.cross(quads[:, 2] - quads[:, 0], quads[:, 3] - quads[:, 1])
    n /= np.linalg.norm(n, axis=1, keepdims=True) + 1e-300
    shade = 0.35 + 0.65 * np.clip(n @ np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8]), 0, 1)
    if values is None:
        colours = np.c_[shade * 0.75, shade * 0.8, shade * 0.9, np.ones_like(shade)]
    else:
        vmax = vmax or float(np.nanpercentile(np.abs(values), 98)) or 1.0
        colours = plt.get_cmap(cmap)(0.5 + 0.5 * np.clip(values / vmax, -1, 1))
        colours[:, :3] *= shade[:, None] * 0.4 + 0.6
    ax.add_collection3d(Poly3DCollection(quads, facecolors=colours, edgecolors="none"))
    lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(np.maximum(hi - lo, 1e-9))
    ax.set_axis_off()


def _gaussian_curvature(mesh) -> np.ndarray:
    """Per face: the mean over its corners of the angle defect / (a third of the corner area)."""
    quads = mesh.face_vertices.reshape(-1, 4)
    V = mesh.vertices
    angle = np.zeros(len(V))
    area = np.zeros(len(V))
    for k in range(4):
        p, a, b = V[quads[:, k]], V[quads[:, (k + 1) % 4]], V[quads[:, (k - 1) % 4]]
        u, w = a - p, b - p
        cos = np.einsum("ij,ij->i", u, w) / (np.linalg.norm(u, axis=1) * np.linalg.norm(w, axis=1))
        np.add.at(angle, quads[:, k], np.arccos(np.clip(cos, -1, 1)))
        np.add.at(area, quads[:, k], np.linalg.norm(np.cross(u, w), axis=1) / 4)
    K = (2 * np.pi - angle) / np.maximum(area, 1e-300)
    return K[quads].mean(axis=1)


def _with_default_vectors(mesh, line: list[tuple[int, int]], s: float, scale: float = 1.0):
    """Line vectors along ``line`` set to scale * (control point - limit point) ([KSD] sec. 4's
    default, Fig. 6)."""
    from patching.curves.surface_vectors import LINE, SurfaceVector

    L = _limit_points(mesh)
    vecs = [SurfaceVector(LINE, v, w, s) for v, w in line]
    W = np.array([scale * (mesh.vertices[v] - L[v]) for v, _ in line])
    return vecs, W


def _shape(shapes: Path, name: str, steps: int):
    """An OpenSubdiv regression shape after ``steps`` Catmull-Clark steps, or None if absent."""
    import warnings

    from patching.mesh.obj import read_obj
    from patching.subdivision.catmark import subdivide

    src = shapes / name
    if not src.exists():
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return subdivide(read_obj(src), steps, rules="opensubdiv")


def figure_13(out: Path, shapes: Path) -> None:
    """[KSD] Fig. 13 in spirit: a cube with OpenSubdiv semi-sharp creases (catmark_cube_creases1)
    plus creases from control vectors along two grid lines (sharpness 2 and inf), with a
    Gaussian curvature plot."""
    from patching.curves.surface_vectors import refine
    from patching.subdivision.catmark import subdivide
    from patching.topology.tables import Topology

    mesh = _shape(shapes, "catmark_cube_creases1.obj", 2)
    if mesh is None:
        print("skip figure_13: OpenSubdiv shapes absent")
        return
    topo = Topology(mesh)
    regular = [int(v) for v in np.flatnonzero(topo.valence == 4) if not np.isin(v, topo.edges[topo.edge_sharpness > 0]).any()]
    v = regular[len(regular) // 3]
    w = int(topo.dest[topo.one_ring(v)[0]])
    from patching.curves.surface_vectors import LINE, SurfaceVector

    centre = mesh.vertices.mean(axis=0)

    def outward(line, s):  # P - limit vanishes on flat faces: push out by a fixed length
        d = mesh.vertices[[a for a, _ in line]] - centre
        return [SurfaceVector(LINE, a, b, s) for a, b in line], 0.25 * d / np.linalg.norm(d, axis=1, keepdims=True)

    line = _walk_line(mesh, v, w, 8)
    vecs, W = outward(line, math.inf)
    v2 = regular[2 * len(regular) // 3]
    line2 = _walk_line(mesh, v2, int(topo.dest[topo.one_ring(v2)[1]]), 8)
    vecs2, W2 = outward(line2, 2.0)
    fine, _, _ = refine(mesh, vecs + vecs2, np.r_[W, W2], 3)
    plain = subdivide(mesh, 3, rules="opensubdiv")
    print(f"figure_13: {len(vecs)} vectors (s = inf), {len(vecs2)} (s = 2)")
    fig = plt.figure(figsize=(12, 4.5))
    for k, (m_, title, curv) in enumerate([(plain, "semi-sharp creases only (OpenSubdiv)", False),
                                          (fine, "+ control vectors (s = inf and 2)", False),
                                          (fine, "Gaussian curvature", True)]):
        ax = fig.add_subplot(1, 3, k + 1, projection="3d")
        _draw_mesh(ax, m_, _gaussian_curvature(m_) if curv else None)
        ax.view_init(28, 35)
        ax.set_title(title, fontsize=9)
    fig.suptitle("[KSD] Fig. 13 (after): Pixar semi-sharp rules and control-vector creases on one model")
    _save(fig, out / "curves_fig13_pixar_and_vectors.png")


def figure_14(out: Path, shapes: Path) -> None:
    """[KSD] Fig. 14 in spirit: a Catmull-Clark torus (catmark_torus; the paper's triple torus
    is not among our shapes) with creases from control vectors along two grid loops."""
    from patching.curves.surface_vectors import refine
    from patching.subdivision.catmark import subdivide
    from patching.topology.tables import Topology

    mesh = _shape(shapes, "catmark_torus.obj", 1)
    if mesh is None:
        print("skip figure_14: OpenSubdiv shapes absent")
        return
    topo = Topology(mesh)
    ring = topo.one_ring(0)
    lines = _walk_line(mesh, 0, int(topo.dest[ring[0]]), 200)
    lines2 = [p for p in _walk_line(mesh, 0, int(topo.dest[ring[1]]), 200) if p[0] != 0]
    vecs, W = _with_default_vectors(mesh, lines + lines2, math.inf, 1.0)
    fine, _, _ = refine(mesh, vecs, W, 3)
    plain = subdivide(mesh, 3, rules="opensubdiv")
    fig = plt.figure(figsize=(10, 4.5))
    for k, (m_, title) in enumerate([(plain, "Catmull-Clark"), (fine, "creases from control vectors along two loops")]):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        _draw_mesh(ax, m_)
        ax.view_init(40, 20)
        ax.set_title(title, fontsize=9)
    fig.suptitle("[KSD] Fig. 14 (after): a torus with creases added by control vectors")
    _save(fig, out / "curves_fig14_torus_vectors.png")


def figure_15(out: Path) -> None:
    """[KSD] Fig. 15: a brick with a ridge crease: control vectors (ours, default setting,
    s = inf) against Pixar's infinitely sharp crease edges; below, the crease curve's height
    profile and its curvature (Pixar's crease flattens towards the brick's ends)."""
    from patching.mesh.control_mesh import from_arrays
    from patching.mesh.primitives import polycube
    from patching.subdivision.catmark import subdivide

    box = polycube([(0, 0, 0), (1, 0, 0), (2, 0, 0)], divisions=4)
    V = box.vertices.copy()
    ridge = np.flatnonzero((np.abs(V[:, 2] - 1) < 1e-9) & (np.abs(V[:, 1] - 0.5) < 1e-9) & (V[:, 0] > 1e-9) & (V[:, 0] < 3 - 1e-9))
    ridge = ridge[np.argsort(V[ridge, 0])]
    V[ridge, 2] += 0.35
    box = box.with_positions(V)
    pairs = [(int(a), int(b)) for a, b in zip(ridge[:-1], ridge[1:])]
    pixar = from_arrays(box.vertices, box.face_vertices.reshape(-1, 4), creases={(min(p), max(p)): math.inf for p in pairs})
    line = [(int(v), int(ridge[min(k + 1, len(ridge) - 1)] if k + 1 < len(ridge) else ridge[k - 1])) for k, v in enumerate(ridge)]
    vecs, W = _with_default_vectors(box, line, math.inf)
    from patching.curves.surface_vectors import refine

    steps = 4
    ours, _, _ = refine(box, vecs, W, steps)
    theirs = subdivide(pixar, steps, rules="opensubdiv")
    fig = plt.figure(figsize=(12, 8))
    for k, (m_, title) in enumerate([(ours, "control vectors (default: P - limit point), s = inf"), (theirs, "Pixar crease rules, s = inf")]):
        ax = fig.add_subplot(2, 2, k + 1, projection="3d")
        _draw_mesh(ax, m_, _gaussian_curvature(m_), vmax=8.0)
        ax.view_init(30, -70)
        ax.set_title(title, fontsize=9)
    bx = fig.add_subplot(2, 2, (3, 4))
    for m_, col, lab in ((ours, "tab:red", "control vectors"), (theirs, "tab:blue", "Pixar crease")):
        P = m_.vertices
        sel = np.flatnonzero((np.abs(P[:, 1] - 0.5) < 1e-9) & (P[:, 2] > 1.0))
        sel = sel[np.argsort(P[sel, 0])]
        x, z = P[sel, 0], P[sel, 2]
        bx.plot(x, z, color=col, lw=1.5, label=f"{lab}: crease height")
        kappa = np.gradient(np.gradient(z, x), x)
        bx.plot(x, 1.0 + 0.02 * kappa, "--", color=col, lw=1, label=f"{lab}: z'' (scaled, offset)")
    bx.legend(fontsize=8)
    bx.set_xlabel("x along the brick")
    bx.set_title("the crease curve (refined control points on the ridge plane, 4 steps)", fontsize=9)
    fig.suptitle("[KSD] Fig. 15: a brick with a ridge crease; colour: Gaussian curvature")
    _save(fig, out / "curves_fig15_brick_crease.png")


def timings() -> None:
    print(f"{'n':>6} {'d':>2} {'limit() s':>10} {'refine(5) s':>12} {'poles':>7}")
    rng = np.random.default_rng(0)
    for n in (100, 300):
        for d in (3, 5, 7):
            P = rng.normal(size=(n, 3))
            corners = {v: (2.5 if d % 2 else 2.0) for v in range(10, n - 10, 25)}
            c = Curve(P, d, corners=corners)
            t0 = time.perf_counter()
            lim = c.limit()
            t1 = time.perf_counter()
            c.refine(5)
            t2 = time.perf_counter()
            print(f"{n:>6} {d:>2} {t1 - t0:>10.3f} {t2 - t1:>12.3f} {len(lim.poles):>7}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/figures")
    parser.add_argument("--no-timings", action="store_true")
    parser.add_argument("--shapes", default="/work/shared/opensubdiv-shapes", help="OpenSubdiv's regression shapes")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    shapes = Path(args.shapes)
    for f in (figure_1, figure_2, figure_3, figure_4, figure_10, figure_11, figure_12, figure_15):
        f(out)
        print(f"wrote {f.__name__}")
    for f in (figure_13, figure_14):
        f(out, shapes)
        print(f"wrote {f.__name__}")
    if not args.no_timings:
        timings()


if __name__ == "__main__":
    main()
