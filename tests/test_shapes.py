"""Every catmark_* shape of OpenSubdiv's regression suite (../shared/opensubdiv-shapes), with
its tags and with random strip intervals: it builds a valid solid (closed) or shell (open),
G1 off its sharp edges, or is refused with one line of the error family.  Issue 4 will turn
the refusals into builds; this test keeps every shape from crashing meanwhile."""

import warnings

import pytest

import patching
from patching.errors import NupatchError
from tests.conftest import shape_files
from tests.test_g1_patches import with_random_intervals

SHAPES = shape_files("catmark_")


@pytest.mark.skipif(not SHAPES, reason="../shared/opensubdiv-shapes is absent")
@pytest.mark.parametrize("path", SHAPES, ids=[p.stem for p in SHAPES])
@pytest.mark.parametrize("intervals", ["uniform", "random"])
def test_shape_builds_or_is_refused_in_one_line(path, intervals):
    from export import check_continuity, to_shape

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            mesh = patching.read_mesh(path)
            if intervals == "random":
                mesh = with_random_intervals(mesh, 5.0, seed=len(path.stem))
            surface = patching.build(mesh)
        except NupatchError as exc:
            assert str(exc) and "\n" not in str(exc)
            return
    report = check_continuity(to_shape(surface))
    assert report.valid and report.max_gap_relative <= 1e-9
    if surface.topology.is_closed:
        assert report.n_solids == 1 and report.n_free_edges == 0
    else:
        assert report.n_shells == 1
    # G1 wherever the surface is meant to be smooth: edges measured below the sharp-edge
    # threshold of the report must be round-off
    assert report.max_smooth_normal_jump_deg <= 1e-6 or report.n_sharp_edges > 0
