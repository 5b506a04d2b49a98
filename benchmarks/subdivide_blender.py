"""``nupatch subdivide --rules opensubdiv`` against OpenSubdiv inside Blender on the same job.

In process: output faces per second of ``subdivide(mesh, L, rules="opensubdiv")`` (building
the refinement operators and applying them) against Blender's Subdivision Surface modifier
(OpenSubdiv, CPU) evaluated through the depsgraph, the crease tags of the OBJ set as Blender's
edge creases (sharpness / 10, Blender's crease scale) and vertex creases.  Whole process: ``nupatch
subdivide -n L --rules opensubdiv`` (read a tagged OBJ, refine, write OBJ) against a Blender
process that imports the OBJ, sets the creases, applies the modifier and exports OBJ.  Ours in
process is the best of the runs in this process (the rules' caches warm after the first);
Blender's is a fresh process each run (its modifier evaluation alone, timed inside, wall and
CPU).  ``--before CHECKOUT`` times a second checkout's ``nupatch`` beside this one's (in process
in a child process of its own, whole process with its code on PYTHONPATH).

Blender's ``bpy`` module is a benchmark tool only, never a dependency: give its Python with
``--bpy`` (default /work/bpy-venv/bin/python).  Old and new alternate in one run.  Run by hand:
``.venv/bin/python benchmarks/subdivide_blender.py [--mesh catmark_pawn] [--levels 3 4] [--runs 3]
[--bpy PYTHON] [--before CHECKOUT]``.

Measured (catmark_pawn, 5 runs, load 10 on 2 cores; CPU seconds, M output faces/s of CPU):

    level 3   in process: main 0.058 (0.65)  this 0.010 (3.72)  Blender 0.036 (1.05)
              whole:      main 0.60          this 0.45 (0.64x)  Blender 0.71
    level 4   in process: main 0.228 (0.66)  this 0.031 (4.88)  Blender 0.108 (1.40)
              whole:      main 1.21          this 0.83 (0.79x)  Blender 1.05

(child topologies derived from the parent's, uniform quad steps written in CSR order, the
OBJ writer's face lines formatted with numpy: docs/speed.md).
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
t0, c0 = time.perf_counter(), time.process_time()
dg = bpy.context.evaluated_depsgraph_get()
ev = obj.evaluated_get(dg)
faces = len(ev.data.polygons)
t_sub, c_sub = time.perf_counter() - t0, time.process_time() - c0
if mode == "whole":
    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.modifier_apply(modifier="sub")
    bpy.ops.wm.obj_export(filepath=out, export_selected_objects=False, export_materials=False,
                          export_uv=False, export_normals=False, forward_axis="Y", up_axis="Z")
print("RESULT " + json.dumps({"faces": faces, "subdivide": t_sub, "subdivide_cpu": c_sub, "total": time.perf_counter() - start}))
"""

#: Ours in process, in a child process so that two checkouts can be timed side by side: best of
#: ``runs`` after one warm-up, wall and CPU (``process_time``).
OURS = r"""
import json, sys, time, warnings
root, src, levels, runs = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
sys.path.insert(0, root)
from patching.mesh.obj import read_obj
from patching.subdivision.catmark import subdivide
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    mesh = read_obj(src)
faces = subdivide(mesh, levels, rules="opensubdiv").n_faces
wall, cpu = [], []
for _ in range(runs):
    t, c = time.perf_counter(), time.process_time()
    subdivide(mesh, levels, rules="opensubdiv")
    wall.append(time.perf_counter() - t)
    cpu.append(time.process_time() - c)
print("RESULT " + json.dumps({"faces": faces, "wall": min(wall), "cpu": min(cpu)}))
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
    parser.add_argument("--before", help="another checkout (e.g. a git worktree of main) timed side by side")
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT))
    from patching.mesh.obj import read_obj

    path = SHAPES / f"{args.mesh}.obj"
    mesh = read_obj(path)
    checkouts = {"nupatch": ROOT} if not args.before else {"before": Path(args.before).resolve(), "after": ROOT}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        tags = tmp / "tags.json"
        tags.write_text(json.dumps({"creases": [[a, b, s] for (a, b), s in mesh.creases.items()],
                                    "corners": [[v, s] for v, s in mesh.corners.items()]}))
        script = tmp / "blender_job.py"
        script.write_text(BLENDER)
        ours_script = tmp / "ours_job.py"
        ours_script.write_text(OURS)
        print(f"{path.name}: {mesh.n_faces} faces, {len(mesh.creases)} crease edges; {args.runs} runs alternated, best; "
              f"load {os.getloadavg()[0]:.1f}")
        for level in args.levels:
            inproc = {name: [] for name in [*checkouts, "Blender"]}
            whole = {name: [] for name in [*checkouts, "Blender"]}
            faces = {}
            for _ in range(args.runs):
                for name, root in checkouts.items():
                    out = timed_process([sys.executable, str(ours_script), str(root), str(path), str(level), "3"])[2]
                    info = json.loads(out.split("RESULT ", 1)[1])
                    faces[name] = info["faces"]
                    inproc[name].append((info["wall"], info["cpu"]))
                    env = dict(os.environ, PYTHONPATH=str(root))
                    env.pop("PYTHONDONTWRITEBYTECODE", None)
                    whole[name].append(timed_process([sys.executable, "-m", "export.cli", "subdivide", str(path), "-n", str(level),
                                                      "--rules", "opensubdiv", "-o", str(tmp / f"{name}.obj"), "-q"], env, root)[:2])
                res = timed_process([args.bpy, str(script), str(path), str(tmp / "b.obj"), str(level), str(tags), "inproc"])
                info = json.loads(res[2].split("RESULT ", 1)[1])
                faces["Blender"] = info["faces"]
                inproc["Blender"].append((info["subdivide"], info["subdivide_cpu"]))
                whole["Blender"].append(timed_process([args.bpy, str(script), str(path), str(tmp / "b.obj"), str(level), str(tags), "whole"])[:2])
            print(f"  level {level}: faces {faces}")
            bw, bc = np.min([w for w, _ in whole["Blender"]]), np.min([c for _, c in whole["Blender"]])
            for name in inproc:
                w = np.min([x for x, _ in inproc[name]])
                c = np.min([x for _, x in inproc[name]])
                ow, oc = np.min([x for x, _ in whole[name]]), np.min([x for _, x in whole[name]])
                print(f"    {name:8} in process wall {w:6.3f} s = {faces[name] / w / 1e6:5.2f} M faces/s, cpu {c:6.3f} s = "
                      f"{faces[name] / c / 1e6:5.2f} M faces/s;  whole process wall {ow:5.2f} s cpu {oc:5.2f} s"
                      + ("" if name == "Blender" else f" (cpu {oc / bc:4.2f}x, wall {ow / bw:4.2f}x Blender's)"))
        print(f"  load at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
