"""--intervals tags|uniform|chord|centripetal (patching/topology/intervals.py, docs/input.md).

The reference strips are computed here independently: a union-find over the opposite edges
of every quad, in plain Python; the reference intervals are written as explicit OBJ interval
tags on every edge and read back through the normal OBJ path.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import export
import patching
from patching.topology.intervals import INTERVAL_RULES, strip_mean_lengths, with_intervals
from patching.mesh.obj import parse_obj

REPO = Path(__file__).resolve().parent.parent


def reference_strips(mesh) -> dict[tuple[int, int], int]:
    """Edge (a<b) -> strip root, by union-find over opposite edges of quads."""
    parent: dict[tuple[int, int], tuple[int, int]] = {}

    def find(e):
        while parent[e] != e:
            parent[e] = parent[parent[e]]
            e = parent[e]
        return e

    def key(a, b):
        return (min(a, b), max(a, b))

    for f in range(mesh.n_faces):
        face = [int(v) for v in mesh.face(f)]
        edges = [key(face[i], face[(i + 1) % len(face)]) for i in range(len(face))]
        for e in edges:
            parent.setdefault(e, e)
        if len(face) == 4:
            for e1, e2 in ((edges[0], edges[2]), (edges[1], edges[3])):
                r1, r2 = find(e1), find(e2)
                if r1 != r2:
                    parent[r1] = r2
    return {e: find(e) for e in parent}


def reference_mean_lengths(mesh) -> dict[tuple[int, int], float]:
    """Edge -> mean length of the edges of its strip (plain Python)."""
    strips = reference_strips(mesh)
    total: dict = {}
    count: dict = {}
    for (a, b), root in strips.items():
        length = math.dist(mesh.vertices[a].tolist(), mesh.vertices[b].tolist())
        total[root] = total.get(root, 0.0) + length
        count[root] = count.get(root, 0) + 1
    return {e: total[r] / count[r] for e, r in strips.items()}


def untagged_bracket():
    """The L bracket without its interval tags, stretched so that strips differ in length."""
    mesh = patching.read_mesh(REPO / "models" / "l_bracket.obj")
    return replace(mesh, intervals={}, vertices=mesh.vertices * np.array([1.7, 1.0, 0.6]) + 0.1 * np.sin(mesh.vertices[:, [1, 2, 0]] * 3))


def with_explicit_tags(mesh, intervals: dict) -> patching.ControlMesh:
    """The mesh as OBJ text with an interval tag on every edge, read back."""
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in mesh.vertices.tolist()]
    lines += ["f " + " ".join(str(int(v) + 1) for v in mesh.face(f)) for f in range(mesh.n_faces)]
    lines += [f"t interval 2/1/0 {a} {b} {d!r}" for (a, b), d in sorted(intervals.items())]
    return parse_obj("\n".join(lines) + "\n", name=mesh.name)


def coefficients(surface) -> np.ndarray:
    return np.concatenate([g.coefficients.reshape(-1, 3) for g in surface.groups])


def test_chord_equals_explicit_tags_of_the_mean_strip_edge_lengths():
    mesh = untagged_bracket()
    reference = reference_mean_lengths(mesh)
    assert len(set(np.round(list(reference.values()), 9))) > 5  # the strips do differ
    explicit = patching.build(with_explicit_tags(mesh, reference))
    chord = patching.build(with_intervals(mesh, "chord"))
    np.testing.assert_allclose(coefficients(chord), coefficients(explicit), rtol=0, atol=1e-12 * explicit.size)


def test_centripetal_is_the_square_root_of_chord():
    mesh = untagged_bracket()
    reference = {e: math.sqrt(d) for e, d in reference_mean_lengths(mesh).items()}
    topo = patching.Topology(with_intervals(mesh, "centripetal"))
    for (a, b), d in reference.items():
        assert topo.edge_interval[topo.edge_id(a, b)] == pytest.approx(d, rel=1e-12)


def test_tagged_strips_keep_their_tags_and_the_others_get_chord():
    mesh = patching.read_mesh(REPO / "models" / "l_bracket.obj")
    original = patching.Topology(mesh)
    tagged_strips = {int(original.edge_strip[original.edge_id(a, b)]) for a, b in mesh.intervals}
    reference = reference_mean_lengths(mesh)
    topo = patching.Topology(with_intervals(mesh, "chord"))
    changed = 0
    for e, (a, b) in enumerate(topo.edges.tolist()):
        if int(original.edge_strip[e]) in tagged_strips:
            assert topo.edge_interval[e] == original.edge_interval[e]
        else:
            assert topo.edge_interval[e] == pytest.approx(reference[(a, b)], rel=1e-12)
            changed += 1
    assert tagged_strips and changed  # both kinds occur on the bracket


def test_uniform_drops_the_tags_and_tags_is_the_mesh_itself():
    mesh = patching.read_mesh(REPO / "models" / "l_bracket.obj")
    assert with_intervals(mesh, "tags") is mesh
    topo = patching.Topology(with_intervals(mesh, "uniform"))
    assert np.all(topo.strip_interval == 1.0)
    assert set(INTERVAL_RULES) == {"tags", "uniform", "chord", "centripetal"}


@settings(max_examples=20, deadline=None)
@given(scale=st.floats(0.01, 100.0))
def test_chord_scales_with_the_mesh_and_centripetal_with_its_root(scale):
    mesh = untagged_bracket()
    scaled = mesh.with_positions(mesh.vertices * scale)
    base = strip_mean_lengths(mesh)
    np.testing.assert_allclose(strip_mean_lengths(scaled), scale * base, rtol=1e-12)
    t1 = patching.Topology(with_intervals(scaled, "centripetal")).strip_interval
    t0 = patching.Topology(with_intervals(mesh, "centripetal")).strip_interval
    np.testing.assert_allclose(t1, math.sqrt(scale) * t0, rtol=1e-12)


def test_cli_info_and_build_and_subdivide_take_intervals(tmp_path, run_cli):
    mesh = untagged_bracket()
    src = tmp_path / "stretched.obj"
    export.write_obj(mesh, src)
    reference = reference_mean_lengths(mesh)
    result = run_cli("info", src, "--json", "--intervals", "chord")
    assert result.returncode == 0, result.stderr
    info = json.loads(result.stdout)
    assert info["intervals"]["min"] == pytest.approx(min(reference.values()), rel=1e-12)
    assert info["intervals"]["max"] == pytest.approx(max(reference.values()), rel=1e-12)
    # subdivide writes the chosen intervals as tags: zero steps give the mesh with chord tags
    out = tmp_path / "chord.obj"
    result = run_cli("subdivide", src, "-n", "0", "-o", out, "--intervals", "chord")
    assert result.returncode == 0, result.stderr
    topo = patching.Topology(patching.read_mesh(out))
    for (a, b), d in reference.items():
        assert topo.edge_interval[topo.edge_id(a, b)] == pytest.approx(d, rel=1e-12)
    # build takes the option (the surfaces themselves are compared above); a bad rule is one line
    step = tmp_path / "c.brep"
    result = run_cli("build", src, "-o", step, "--intervals", "centripetal", "-q")
    assert result.returncode == 0, result.stderr
    assert step.stat().st_size > 0
    result = run_cli("build", src, "-o", tmp_path / "x.step", "--intervals", "arc")
    assert result.returncode == 2 and len(result.stderr.strip().splitlines()) == 1
    assert "--intervals" in result.stderr and not (tmp_path / "x.step").exists()
