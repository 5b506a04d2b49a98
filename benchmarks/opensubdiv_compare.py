"""``subdivide --rules opensubdiv`` against OpenSubdiv itself, built from its sources (by hand).

    .venv/bin/python benchmarks/opensubdiv_compare.py OSD_SRC [-n 2] [MESH.obj ...]

OSD_SRC is a checkout of PixarAnimationStudios/OpenSubdiv (its ``opensubdiv/`` folder is
enough).  The script compiles a 60-line driver with the sources of ``sdc``, ``vtr`` and the
four ``far`` files that TopologyRefiner needs (g++, C++14, about a minute on a 2-core box), reads
each OBJ with OpenSubdiv's tags (crease, corner, interpolateboundary, creasemethod; a file
without interpolateboundary is given nupatch's default, 1), refines it n levels with
``Far::TopologyRefiner::RefineUniform`` and ``Far::PrimvarRefiner`` (float), and compares the
last level's points with ``patching.subdivision.subdivide(mesh, n, rules="opensubdiv")``.
The two number edges differently, so points are matched as sets (nearest point both ways,
scipy's cKDTree); the figure is the largest distance relative to the mesh's size.  Without
MESH arguments: every catmark shape of ../shared/opensubdiv-shapes that nupatch reads.

Nothing here runs in the tests (CI has no OpenSubdiv); the tests check the same rules against
a loop reference written from OpenSubdiv's definitions (tests/test_subdivision.py).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from patching.errors import NupatchError  # noqa: E402
from patching.mesh.obj import read_obj  # noqa: E402
from patching.subdivision import subdivide  # noqa: E402

DRIVER = r"""
#include <opensubdiv/far/topologyDescriptor.h>
#include <opensubdiv/far/primvarRefiner.h>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>
using namespace OpenSubdiv;
struct V { float p[3]; void Clear(void* = 0) { p[0] = p[1] = p[2] = 0; }
  void AddWithWeight(V const& s, float w) { for (int i = 0; i < 3; i++) p[i] += w * s.p[i]; } };
int main(int argc, char** argv) {
  std::ifstream in(argv[1]); int levels = atoi(argv[2]);
  std::vector<float> pos, cs, vsh; std::vector<int> nv, fv, ce, cv; int ib = 1; bool chaikin = false;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream ss(line); std::string tok; ss >> tok;
    if (tok == "v") { float x, y, z; ss >> x >> y >> z; pos.push_back(x); pos.push_back(y); pos.push_back(z); }
    else if (tok == "f") { int n = 0; std::string w; while (ss >> w) { fv.push_back(atoi(w.c_str()) - 1); n++; } nv.push_back(n); }
    else if (tok == "t") { std::string name, cnt; ss >> name >> cnt;
      if (name == "crease") { int a, b; float s; ss >> a >> b >> s; ce.push_back(a); ce.push_back(b); cs.push_back(s); }
      else if (name == "corner") { int a; float s; ss >> a >> s; cv.push_back(a); vsh.push_back(s); }
      else if (name == "interpolateboundary") { ss >> ib; }
      else if (name == "creasemethod") { std::string m; ss >> m; chaikin = (m == "chaikin"); } } }
  typedef Far::TopologyDescriptor Desc;
  Desc d; d.numVertices = pos.size() / 3; d.numFaces = nv.size(); d.numVertsPerFace = nv.data();
  d.vertIndicesPerFace = fv.data(); d.numCreases = cs.size(); d.creaseVertexIndexPairs = ce.data();
  d.creaseWeights = cs.data(); d.numCorners = vsh.size(); d.cornerVertexIndices = cv.data(); d.cornerWeights = vsh.data();
  Sdc::Options o;
  o.SetVtxBoundaryInterpolation(ib == 0 ? Sdc::Options::VTX_BOUNDARY_NONE : ib == 1 ?
      Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER : Sdc::Options::VTX_BOUNDARY_EDGE_ONLY);
  if (chaikin) o.SetCreasingMethod(Sdc::Options::CREASE_CHAIKIN);
  Far::TopologyRefiner* r = Far::TopologyRefinerFactory<Desc>::Create(d,
      Far::TopologyRefinerFactory<Desc>::Options(Sdc::SCHEME_CATMARK, o));
  r->RefineUniform(Far::TopologyRefiner::UniformOptions(levels));
  std::vector<V> verts(r->GetNumVerticesTotal());
  for (int i = 0; i < d.numVertices; i++) for (int k = 0; k < 3; k++) verts[i].p[k] = pos[3 * i + k];
  Far::PrimvarRefiner pr(*r); V* src = verts.data();
  for (int l = 1; l <= levels; l++) { V* dst = src + r->GetLevel(l - 1).GetNumVertices(); pr.Interpolate(l, src, dst); src = dst; }
  for (int i = 0; i < r->GetLevel(levels).GetNumVertices(); i++) printf("%.9g %.9g %.9g\n", src[i].p[0], src[i].p[1], src[i].p[2]);
  return 0;
}
"""


def build_driver(osd: Path, work: Path) -> Path:
    """Compile the driver against the OpenSubdiv sources in ``osd``; the executable's path."""
    root = osd / "opensubdiv"
    sources = sorted((root / "sdc").glob("*.cpp")) + sorted((root / "vtr").glob("*.cpp"))
    sources += [root / "far" / f for f in ("topologyRefiner.cpp", "topologyRefinerFactory.cpp", "topologyDescriptor.cpp", "error.cpp")]
    (work / "main.cpp").write_text(DRIVER)
    exe = work / "osd_refine"
    subprocess.run(["g++", "-O1", "-std=c++14", f"-I{osd}", *map(str, sources), str(work / "main.cpp"), "-o", str(exe)], check=True)
    return exe


def compare(exe: Path, path: Path, steps: int) -> tuple[int, int, float]:
    """(points, points off by more than 1e-5 of the size, largest distance / size)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mesh = read_obj(path)
    ours = subdivide(mesh, steps, rules="opensubdiv").vertices
    text = path.read_text()
    if "interpolateboundary" not in text:  # nupatch's default, 1, for OpenSubdiv too
        tmp = exe.parent / "with_tag.obj"
        tmp.write_text(text + "\nt interpolateboundary 1/0/0 1\n")
        path = tmp
    out = subprocess.run([str(exe), str(path), str(steps)], capture_output=True, text=True, check=True).stdout
    ref = np.loadtxt(out.splitlines(), ndmin=2)
    size = float(np.ptp(mesh.vertices, axis=0).max())
    if len(ref) != len(ours):
        return len(ours), len(ours), np.inf
    d1, _ = cKDTree(ref).query(ours)
    d2, _ = cKDTree(ours).query(ref)
    return len(ours), int((np.maximum(d1, d2) > 1e-5 * size).sum()), float(max(d1.max(), d2.max()) / size)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("osd", type=Path, help="OpenSubdiv source checkout")
    ap.add_argument("meshes", nargs="*", type=Path)
    ap.add_argument("-n", type=int, default=2, help="levels (default 2)")
    args = ap.parse_args()
    meshes = args.meshes or sorted((Path(__file__).resolve().parents[2] / "shared" / "opensubdiv-shapes").glob("catmark_*.obj"))
    with tempfile.TemporaryDirectory() as tmp:
        exe = build_driver(args.osd, Path(tmp))
        print(f"{'mesh':<34} {'points':>7} {'off':>5} {'max/size':>10}")
        for path in meshes:
            try:
                n, off, worst = compare(exe, path, args.n)
            except NupatchError as exc:
                print(f"{path.stem:<34} skipped: {str(exc).splitlines()[0][:60]}")
                continue
            print(f"{path.stem:<34} {n:>7} {off:>5} {worst:10.2e}")


if __name__ == "__main__":
    main()
