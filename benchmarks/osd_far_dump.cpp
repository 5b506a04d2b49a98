// Uniform refinement of one OBJ shape by OpenSubdiv's Far (Sdc/Vtr/Far, not Hbr), for
// benchmarks/osd_far_reference.py.  The shape is parsed by OpenSubdiv's own regression parser
// (regression/common/shape_utils.cpp: float32 positions and sharpness, `t` tags, the
// creasemethod and interpolateboundary options of regression/common/far_utils.h); positions are
// refined with Far::PrimvarRefinerReal<double>.  Prints, per level, "level L nverts nfaces", the
// vertices ("v x y z", 17 digits) and the faces ("f i j k", 0-based).
//
//   osd_far_dump SHAPE.obj MAXLEVEL [loop|catmark]
#include "far_utils.h"

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

struct Point {
    double p[3];
    void Clear() { p[0] = p[1] = p[2] = 0.0; }
    void AddWithWeight(Point const& s, double w) {
        for (int k = 0; k < 3; ++k) p[k] += w * s.p[k];
    }
};

int main(int argc, char** argv) {
    if (argc < 3) {
        std::fprintf(stderr, "usage: osd_far_dump SHAPE.obj MAXLEVEL [loop|catmark]\n");
        return 2;
    }
    std::ifstream in(argv[1]);
    std::stringstream text;
    text << in.rdbuf();
    int maxlevel = std::atoi(argv[2]);
    Scheme scheme = (argc > 3 && std::string(argv[3]) == "catmark") ? kCatmark : kLoop;
    Shape* shape = Shape::parseObj(text.str().c_str(), scheme);

    typedef OpenSubdiv::Far::TopologyRefinerFactory<Shape> Factory;
    OpenSubdiv::Far::TopologyRefiner* refiner =
        Factory::Create(*shape, Factory::Options(GetSdcType(*shape), GetSdcOptions(*shape)));
    if (!refiner) return 1;
    OpenSubdiv::Far::TopologyRefiner::UniformOptions options(maxlevel);
    options.fullTopologyInLastLevel = true;
    refiner->RefineUniform(options);

    std::vector<Point> data(refiner->GetNumVerticesTotal());
    for (int i = 0; i < refiner->GetLevel(0).GetNumVertices(); ++i)
        for (int k = 0; k < 3; ++k) data[i].p[k] = shape->verts[3 * i + k];
    OpenSubdiv::Far::PrimvarRefinerReal<double> primvar(*refiner);

    Point* src = &data[0];
    for (int level = 0; level <= maxlevel; ++level) {
        OpenSubdiv::Far::TopologyLevel const& tl = refiner->GetLevel(level);
        if (level > 0) {
            Point* dst = src + refiner->GetLevel(level - 1).GetNumVertices();
            primvar.Interpolate(level, src, dst);
            src = dst;
        }
        std::printf("level %d %d %d\n", level, tl.GetNumVertices(), tl.GetNumFaces());
        for (int i = 0; i < tl.GetNumVertices(); ++i)
            std::printf("v %.17g %.17g %.17g\n", src[i].p[0], src[i].p[1], src[i].p[2]);
        for (int f = 0; f < tl.GetNumFaces(); ++f) {
            OpenSubdiv::Far::ConstIndexArray fv = tl.GetFaceVertices(f);
            std::printf("f");
            for (int k = 0; k < fv.size(); ++k) std::printf(" %d", fv[k]);
            std::printf("\n");
        }
    }
    delete refiner;
    delete shape;
    return 0;
}
