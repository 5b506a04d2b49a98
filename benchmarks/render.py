"""Time of ``nupatch render`` pictures at 1600 x 1200 (the target: under 5 s each) on
models/l_bracket.obj and models/machined_bracket.obj, in one process after a warm-up picture
(imports and VTK's first context excluded), split into build, sampling and drawing; CPU
seconds beside the wall-clock ones (a shared machine's wall clock includes other work).

    .venv/bin/python benchmarks/render.py [--size 1600x1200] [--modes zebra,mean,blending]
    .venv/bin/python benchmarks/render.py --figure docs/figures/zebra_g0_g1.png

--figure draws docs/pictures.md's G0/G1 picture instead: ``tests.helpers.roof_mesh`` with its
ridge creased (G0) and not (G1), zebra from the top with light lines at 45 degrees, side by
side (the configuration ``tests/test_render.py`` judges by its pixels).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import patching
from export.render import Picture, picture_pixel, render, sample_surface
from export.render_blending import control_points, surface_field
from export.render_geometry import grid_size

MODELS = ("l_bracket", "machined_bracket")


def clocks():
    return time.perf_counter(), time.process_time()


def since(start) -> tuple[float, float]:
    wall, cpu = clocks()
    return wall - start[0], cpu - start[1]


def picture(name: str, mode: str, size: tuple[int, int], out: Path) -> dict:
    t = clocks()
    mesh = patching.read_mesh(ROOT / "models" / f"{name}.obj")
    operator = patching.build_operator(mesh)
    surface = operator.evaluate(mesh.vertices)
    build = since(t)
    t = clocks()
    pic = Picture()
    coefficients = np.concatenate([g.coefficients.reshape(-1, 3) for g in surface.groups])
    pixel = picture_pixel(coefficients, size, pic, mode not in ("zebra", "shaded"))
    m = grid_size(surface, pixel)
    sampled = sample_surface(surface, pixel, m=m)
    if mode == "blending":
        sampled = surface_field(operator, surface, sampled, control_points("ep", mesh, operator), m, "EPs")
    sample = since(t)
    t = clocks()
    used = render(sampled, out / f"{name}_{mode}.png", mode, size, picture=pic)
    draw = since(t)
    return {"build": build, "sample": sample, "draw": draw, "m": m, "vertices": len(sampled.points), "used": used}


def g0_g1_figure(path: Path, side: int = 400) -> None:
    """The roof with a G0 ridge (left) and a G1 one (right), zebra from the top."""
    from export.atomic import atomic_output
    from export.render_scene import write_png
    from tests.helpers import roof_mesh

    pic = Picture(view="top", stripes=12, stripe_direction=45.0)
    images = []
    with tempfile.TemporaryDirectory() as tmp:
        for crease in (True, False):
            surface = patching.build(roof_mesh(crease=crease))
            coefficients = np.concatenate([g.coefficients.reshape(-1, 3) for g in surface.groups])
            sampled = sample_surface(surface, picture_pixel(coefficients, (side, side), pic, False))
            out = Path(tmp) / f"{crease}.png"
            render(sampled, out, "zebra", (side, side), picture=pic)
            from matplotlib import image as mpimg

            images.append((mpimg.imread(out)[..., :3] * 255).round().astype(np.uint8))
    gap = np.full((side, side // 20, 3), 255, np.uint8)
    with atomic_output(path) as tmp_path:
        write_png(np.concatenate([images[0], gap, images[1]], axis=1), Path(tmp_path))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="1600x1200")
    parser.add_argument("--modes", default="zebra,mean,blending")
    parser.add_argument("--figure", type=Path, help="draw the G0/G1 zebra figure to this PNG instead")
    args = parser.parse_args()
    if args.figure:
        g0_g1_figure(args.figure)
        return
    size = tuple(int(x) for x in args.size.split("x"))
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        picture("l_bracket", "shaded", (160, 120), out)  # warm-up: imports, the first GL context
        print(f"{'model':18} {'mode':9} {'m':>4} {'vertices':>9} {'build':>11} {'sample':>11} {'draw':>11} {'total':>11}  (wall/cpu s)")
        for name in MODELS:
            for mode in args.modes.split(","):
                r = picture(name, mode, size, out)
                total = tuple(sum(r[k][i] for k in ("build", "sample", "draw")) for i in (0, 1))
                cells = " ".join(f"{r[k][0]:5.2f}/{r[k][1]:5.2f}" for k in ("build", "sample", "draw"))
                print(f"{name:18} {mode:9} {r['m']:4d} {r['vertices']:9d} {cells} {total[0]:5.2f}/{total[1]:5.2f}  {r['used']}")


if __name__ == "__main__":
    main()
