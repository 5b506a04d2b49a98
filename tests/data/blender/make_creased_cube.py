"""Writes ``creased_cube.usda`` with Blender itself (the ``bpy`` module from the package index):

    python -m venv /tmp/bpy && /tmp/bpy/bin/pip install bpy
    /tmp/bpy/bin/python tests/data/blender/make_creased_cube.py -- tests/data/blender/creased_cube.usda

The committed file was written by bpy 5.0.1 (Blender 5.0.1): a 2 x 2 x 2 cube moved to x = 10,
edge creases 1.0 on the four edges of the top face and 0.5 on one vertical edge, vertex crease 1.0
on one bottom vertex, a Subdivision Surface modifier, and USD export with
``export_subdivision='BEST_MATCH'`` (Blender writes the modifier as ``subdivisionScheme`` and its
creases as ``creaseIndices``/``cornerIndices`` with sharpness 10 c^2). bpy needs numpy < 2, so it
cannot share the test environment; tests/test_usd.py reads this file and, where ``bpy`` imports,
exports a fresh one the same way.
"""

import sys

import bpy  # first: it makes bmesh importable
import bmesh  # noqa: E402


def creased_cube(path: str) -> None:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    mesh = bpy.data.meshes.new("CreasedCube")
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=2.0)
    bm.to_mesh(mesh)
    bm.free()
    obj = bpy.data.objects.new("CreasedCube", mesh)
    bpy.context.scene.collection.objects.link(obj)
    z = [v.co.z for v in mesh.vertices]
    edge_crease = mesh.attributes.new("crease_edge", "FLOAT", "EDGE")
    for e in mesh.edges:
        a, b = e.vertices
        if z[a] > 0 and z[b] > 0:
            edge_crease.data[e.index].value = 1.0
    vertical = next(e for e in mesh.edges if z[e.vertices[0]] * z[e.vertices[1]] < 0)
    edge_crease.data[vertical.index].value = 0.5
    vertex_crease = mesh.attributes.new("crease_vert", "FLOAT", "POINT")
    vertex_crease.data[next(v.index for v in mesh.vertices if v.co.z < 0)].value = 1.0
    obj.modifiers.new("Subdivision", "SUBSURF")
    obj.location = (10.0, 0.0, 0.0)
    bpy.ops.wm.usd_export(filepath=path, export_subdivision="BEST_MATCH", selected_objects_only=False)


if __name__ == "__main__":
    creased_cube(sys.argv[-1])
