"""An independent, obviously-correct Loop refinement for the tests: plain Python loops over
vertices and edges, following [OSD]'s ``Scheme::ComputeVertexVertexMask`` /
``ComputeEdgeVertexMask`` control flow line by line, with dicts for the topology.  It shares
no code with ``patching.loop``.  Child numbering as ``patching.loop.refine`` (vertex points
keep their ids, then one edge point per edge in sorted (min, max) order)."""

from __future__ import annotations

import math

INF = 10.0
#: cos and pi of the smooth vertex mask; the tests swap in mpmath's for exact high-precision runs
COS, PI = math.cos, math.pi


def _dec(s):
    if s <= 0:
        return 0.0
    if s >= INF:
        return s
    return s - 1.0 if s > 1.0 else 0.0


class RefMesh:
    def __init__(self, points, faces, creases=None, corners=None, boundary_mode=1, method="uniform"):
        self.P = [tuple(p) for p in points]
        self.faces = [tuple(int(x) for x in f) for f in faces]
        self.creases = dict(creases or {})  # (a, b) a < b -> s
        self.corners = dict(corners or {})
        self.mode = boundary_mode
        self.method = method

    # topology
    def edges(self):
        es = set()
        for f in self.faces:
            for i in range(3):
                a, b = f[i], f[(i + 1) % 3]
                es.add((min(a, b), max(a, b)))
        return sorted(es)

    def step(self):
        edges = self.edges()
        eid = {e: i for i, e in enumerate(edges)}
        efaces = {e: [] for e in edges}
        for fi, f in enumerate(self.faces):
            for i in range(3):
                a, b = f[i], f[(i + 1) % 3]
                efaces[(min(a, b), max(a, b))].append(fi)
        nv = len(self.P)
        vedges = {v: [] for v in range(nv)}
        vfaces = {v: [] for v in range(nv)}
        for e in edges:
            vedges[e[0]].append(e)
            vedges[e[1]].append(e)
        for fi, f in enumerate(self.faces):
            for v in f:
                vfaces[v].append(fi)
        # sharpness as the refiner factory sets it
        esharp = {}
        for e in edges:
            s = float(self.creases.get(e, 0.0))
            if len(efaces[e]) == 1:
                s = INF
            esharp[e] = s
        vsharp = {}
        for v in range(nv):
            s = float(self.corners.get(v, 0.0))
            if self.mode == 1 and len(vfaces[v]) == 1 and len(vedges[v]) == 2:
                s = INF
            vsharp[v] = s

        def child_half(e, v):
            """sharpness of the half of e at v (Crease::SubdivideEdgeSharpnessAtVertex)."""
            s = esharp[e]
            if self.method == "uniform" or len(vedges[v]) < 2:
                return _dec(s)
            if s <= 0:
                return 0.0
            if s >= INF:
                return s
            semi = [esharp[x] for x in vedges[v] if 0 < esharp[x] < INF]
            if len(semi) > 1:
                avg = (sum(semi) - s) / (len(semi) - 1)
                s = 0.75 * s + 0.25 * avg
            s -= 1.0
            return s if s > 0 else 0.0

        def rule(vs, sharp_count):
            if vs > 0:
                return "corner"
            return {0: "smooth", 1: "dart", 2: "crease"}.get(sharp_count, "corner")

        def other(e, v):
            return e[1] if e[0] == v else e[0]

        new = []
        # vertex points
        for v in range(nv):
            P = self.P
            ve = vedges[v]
            n = len(vfaces[v])
            psharp = [esharp[e] for e in ve]
            csharp = [child_half(e, v) for e in ve]
            prule = rule(vsharp[v], sum(1 for s in psharp if s > 0))
            crule = rule(_dec(vsharp[v]), sum(1 for s in csharp if s > 0))

            def mask(r, sharp):
                m = {}
                if r in ("smooth", "dart"):
                    if n == 6:
                        beta = 0.0625
                    else:
                        c = 0.375 + 0.25 * COS(2 * PI / n)
                        beta = (0.625 - c * c) / n
                    m[v] = 1.0 - beta * len(ve)
                    for e in ve:
                        m[other(e, v)] = m.get(other(e, v), 0.0) + beta
                elif r == "crease":
                    m[v] = 0.75
                    ends = [other(e, v) for e, s in zip(ve, sharp) if s > 0][:2]
                    for x in ends:
                        m[x] = m.get(x, 0.0) + 0.125
                else:
                    m[v] = 1.0
                return m

            if prule in ("smooth", "dart"):
                m = mask(prule, psharp)
            else:
                m = mask(prule, psharp)
                if crule != prule:
                    cm = mask(crule, csharp)
                    tsum, tcnt = 0.0, 0
                    if vsharp[v] > 0 and _dec(vsharp[v]) <= 0:
                        tsum, tcnt = vsharp[v], 1
                    for ps, cs in zip(psharp, csharp):
                        if ps > 0 and cs <= 0:
                            tsum += ps
                            tcnt += 1
                    w = min(tsum / tcnt, 1.0) if tcnt else 0.0
                    keys = set(m) | set(cm)
                    m = {k: w * m.get(k, 0.0) + (1 - w) * cm.get(k, 0.0) for k in keys}
            new.append(tuple(sum(wt * P[k][d] for k, wt in m.items()) for d in range(3)))
        # edge points
        for e in edges:
            a, b = e
            P = self.P
            opp = []
            for fi in efaces[e]:
                opp += [x for x in self.faces[fi] if x not in e]
            s = esharp[e]
            smooth = {a: 0.375, b: 0.375}
            for x in opp:
                smooth[x] = smooth.get(x, 0.0) + 0.125
            if s <= 0:
                m = smooth
            else:
                child_crease = child_half(e, a) > 0 and child_half(e, b) > 0
                if child_crease:
                    m = {a: 0.5, b: 0.5}
                else:
                    m = {k: (1 - s) * w for k, w in smooth.items()}
                    m[a] += 0.5 * s
                    m[b] += 0.5 * s
            new.append(tuple(sum(wt * P[k][d] for k, wt in m.items()) for d in range(3)))
        # child topology and tags
        faces = []
        for f in self.faces:
            E = [nv + eid[(min(f[i], f[(i + 1) % 3]), max(f[i], f[(i + 1) % 3]))] for i in range(3)]
            for i in range(3):
                faces.append((f[i], E[i], E[(i - 1) % 3]))
            faces.append(tuple(E))
        creases = {}
        for e in edges:
            if len(efaces[e]) == 1:
                continue
            for v in e:
                c = child_half(e, v)
                if c > 0:
                    creases[(min(v, nv + eid[e]), max(v, nv + eid[e]))] = c
        corners = {v: _dec(s) for v, s in self.corners.items() if _dec(s) > 0}
        return RefMesh(new, faces, creases, corners, self.mode, self.method)
