"""``nupatch subdivide --rules opensubdiv`` against OpenSubdiv inside Blender on the same job.

In process: output faces per second of ``subdivide(mesh, L, rules="opensubdiv")`` (building
the refinement operators and applying them) against Blender's Subdivision Surface modifier
(OpenSubdiv, CPU) evaluated through the depsgraph, the crease tags of the OBJ set as Blender's
edge creases (sharpness / 10, Blender's crease scale) and vertex creases.  Whole process: ``nupatch
subdivide -n L --rules opensubdiv`` (read a tagged OBJ, refine, write OBJ) against a Blender
process that imports the OBJ, sets the creases, applies the modifier and exports OBJ.  Ours in
process is the best of the runs in this process (the rules' caches warm after the first);
Blender's is a fresh process each run (its modifier evaluation alone, timed inside).

Blender's ``bpy`` module is a benchmark tool only, never a dependency: give its Python with
``--bpy`` (default /work/bpy-venv/bin/python).  Old and new alternate in one run.  Run by hand:
``.venv/bin/python benchmarks/subdivide_blender.py [--mesh catmark_pawn] [--levels 3 4] [--runs 3]``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SHAPES = ROOT.parent / "shared" / "opensubdiv-shapes"

BLENDER = r"""
import json, sys, time
import bpy, bmesh
src, out, levels, tags_path, mode = sys.argv[-5:]
levels = int(levels)
tags = json.load(open(tags_path))
start = time.perf_counter()
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.wm.obj_import(filepath=src, forward_axis="Y", up_axis="Z")
obj = bpy.context.selected_objects[0]
me = obj.data
# creases: OpenSubdiv sharpness s -> Blender crease s / 10 (clamped to 1)
edge_index = {tuple(sorted(e.vertices)): e.index for e in me.edges}
crease = me.attributes.get("crease_edge") or me.attributes.new("crease_edge", "FLOAT", "EDGE")
for a, b, s in tags["creases"]:
    k = edge_index.get((min(a, b), max(a, b)))
    if k is not None:
        crease.data[k].value = min(s / 10.0, 1.0)
if tags["corners"]:
    vc = me.attributes.get("crease_vert") or me.attributes.new("crease_vert", "FLOAT", "POINT")
    for v, s in tags["corners"]:
        vc.data[v].value = min(s / 10.0, 1.0)
mod = obj.modifiers.new("sub", "SUBSURF")
mod.levels = mod.render_levels = levels
mod.quality = 3
t0 = time.perf_counter()
dg = bpy.context.evaluated_depsgraph_get()
ev = obj.evaluated_get(dg)
faces = len(ev.data.polygons)
t_sub = time.perf_counter() - t0
if mode == "whole":
    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.modifier_apply(modifier="sub")
    bpy.ops.wm.obj_export(filepath=out, export_selected_objects=False, export_materials=False,
                          export_uv=False, export_normals=False, forward_axis="Y", up_axis="Z")
print("RESULT " + json.dumps({"faces": faces, "subdivide": t_sub, "total": time.perf_counter() - start}))
"""


def timed_process(cmd: list[str], env=None, cwd=None) -> tuple[float, float, str]:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    out = subprocess.run(cmd, check=True, env=env, capture_output=True, text=True, cwd=cwd).stdout
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--mesh", default="catmark_pawn")
    parser.add_argument("--levels", type=int, nargs="+", default=[3, 4])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--bpy", default="/work/bpy-venv/bin/python")
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT))
    from patching.mesh.obj import read_obj
    from patching.subdivision.catmark import subdivide

    path = SHAPES / f"{args.mesh}.obj"
    mesh = read_obj(path)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        tags = tmp / "tags.json"
        tags.write_text(json.dumps({"creases": [[a, b, s] for (a, b), s in mesh.creases.items()],
                                    "corners": [[v, s] for v, s in mesh.corners.items()]}))
        script = tmp / "blender_job.py"
        script.write_text(BLENDER)
        print(f"{path.name}: {mesh.n_faces} faces, {len(mesh.creases)} crease edges; {args.runs} runs alternated, best")
        for level in args.levels:
            ours, theirs, ours_whole, theirs_whole = [], [], [], []
            faces = 0
            for _ in range(args.runs):
                t = time.perf_counter()
                refined = subdivide(mesh, level, rules="opensubdiv")
                ours.append(time.perf_counter() - t)
                faces = refined.n_faces
                res = timed_process([args.bpy, str(script), str(path), str(tmp / "b.obj"), str(level), str(tags), "inproc"])
                info = json.loads(res[2].split("RESULT ", 1)[1])
                theirs.append(info["subdivide"])
                ours_whole.append(timed_process([sys.executable, "-m", "export.cli", "subdivide", str(path), "-n", str(level),
                                                 "--rules", "opensubdiv", "-o", str(tmp / "n.obj"), "-q"], env, tmp)[:2])
                theirs_whole.append(timed_process([args.bpy, str(script), str(path), str(tmp / "b.obj"), str(level), str(tags), "whole"])[:2])
            print(f"  level {level}: {faces} faces (Blender {info['faces']})")
            print(f"    in process   nupatch {min(ours):6.3f} s = {faces / min(ours) / 1e6:5.2f} M faces/s;"
                  f"  Blender/OpenSubdiv {min(theirs):6.3f} s = {info['faces'] / min(theirs) / 1e6:5.2f} M faces/s")
            ow, oc = np.min([w for w, _ in ours_whole]), np.min([c for _, c in ours_whole])
            bw, bc = np.min([w for w, _ in theirs_whole]), np.min([c for _, c in theirs_whole])
            print(f"    whole process nupatch wall {ow:6.2f} s cpu {oc:6.2f} s;  Blender wall {bw:6.2f} s cpu {bc:6.2f} s;"
                  f"  ratio cpu {oc / bc:4.2f}")


if __name__ == "__main__":
    main()
