"""Export time and size per format on a 100 x 100 torus (10,000 faces, intervals 1 to 20).

    .venv/bin/python benchmarks/formats.py [--size 100]

Prints, per format: the write time from a built B-rep (for stl/glb/obj including the
tessellation with the same deflection, and our patch normals), the file size, and for reference
OpenCASCADE's own writer where OCP has one (StlAPI_Writer for STL, RWGltf_CafWriter for glTF;
both write facet-derived or no normals), measured in the same run on a fresh copy of the B-rep,
meshing included.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

import patching
from export.brep import to_shape
from OCP.BRepMesh import BRepMesh_IncrementalMesh

from export.formats import ANGULAR_DEFLECTION, FORMATS, RELATIVE_TOLERANCE, tessellate, write
from patching.mesh.primitives import torus_grid


def occ_writer(fmt: str, shape, path: Path):
    """OpenCASCADE's own writer for a tessellated format, or None."""
    if fmt == "stl":
        from OCP.StlAPI import StlAPI_Writer

        def run():
            writer = StlAPI_Writer()
            writer.ASCIIMode = False  # binary, as ours
            writer.Write(shape, str(path))

        return run
    if fmt == "glb":
        from OCP.Message import Message_ProgressRange
        from OCP.RWGltf import RWGltf_CafWriter
        from OCP.TCollection import TCollection_AsciiString, TCollection_ExtendedString
        from export.ocp_compat import TColStd_IndexedDataMapOfStringString
        from OCP.TDocStd import TDocStd_Document
        from OCP.XCAFDoc import XCAFDoc_DocumentTool

        doc = TDocStd_Document(TCollection_ExtendedString("doc"))
        XCAFDoc_DocumentTool.ShapeTool_s(doc.Main()).AddShape(shape)

        def run():
            writer = RWGltf_CafWriter(TCollection_AsciiString(str(path)), True)
            writer.Perform(doc, TColStd_IndexedDataMapOfStringString(), Message_ProgressRange())

        return run
    return None


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--size", type=int, default=100)
    args = parser.parse_args()
    n = args.size
    rng = np.random.default_rng(0)
    mesh = torus_grid(n, n, rng.integers(1, 21, n).astype(float), rng.integers(1, 21, n).astype(float), name="torus")
    start = time.perf_counter()
    surface = patching.build(mesh)
    t_build = time.perf_counter() - start
    start = time.perf_counter()
    shape = to_shape(surface)
    t_brep = time.perf_counter() - start
    start = time.perf_counter()
    tess = tessellate(surface, shape)
    t_tess = time.perf_counter() - start
    print(f"{n} x {n} torus: {surface.n_patches} patches; build {t_build:.2f} s, B-rep {t_brep:.2f} s, "
          f"tessellation {t_tess:.2f} s ({len(tess.points)} vertices, {len(tess.triangles)} triangles, with patch normals)")
    print(f"{'format':<7} {'ours (s)':>9} {'size (MB)':>10} {'OCC writer (s)':>15} {'size (MB)':>10} {'ratio':>6}")
    with tempfile.TemporaryDirectory() as tmp:
        for fmt in FORMATS:
            path = Path(tmp) / f"t.{fmt}"
            fresh = to_shape(surface)  # untessellated: each tessellated format meshes it once
            start = time.perf_counter()
            write(surface, path, fmt, shape=fresh)
            ours = time.perf_counter() - start
            size = os.path.getsize(path) / 1e6
            other = to_shape(surface)
            ref = occ_writer(fmt, other, Path(tmp) / f"occ.{fmt}")
            if ref is None:
                print(f"{fmt:<7} {ours:9.2f} {size:10.1f} {'-':>15} {'-':>10} {'-':>6}")
                continue
            start = time.perf_counter()
            BRepMesh_IncrementalMesh(other, RELATIVE_TOLERANCE * surface.size, False, ANGULAR_DEFLECTION, False)
            ref()
            theirs = time.perf_counter() - start
            occ_size = os.path.getsize(Path(tmp) / f"occ.{fmt}") / 1e6
            print(f"{fmt:<7} {ours:9.2f} {size:10.1f} {theirs:15.2f} {occ_size:10.1f} {ours / theirs:6.2f}")


if __name__ == "__main__":
    main()
