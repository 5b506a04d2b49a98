"""The environment imports one OpenCASCADE: cadquery and build123d share the same OCP module."""

import importlib.metadata as md

import pytest


def test_one_ocp_wheel_is_installed():
    installed = {d.metadata["Name"].lower() for d in md.distributions()}
    assert "cadquery-ocp" in installed
    assert "cadquery-ocp-novtk" not in installed, "a second OCP wheel would overwrite the first file by file"


def test_cadquery_and_build123d_share_one_ocp():
    import OCP
    import OCP.TopoDS

    cadquery = pytest.importorskip("cadquery")
    build123d = pytest.importorskip("build123d")
    box_cq = cadquery.Workplane().box(1, 2, 3).val().wrapped
    box_bd = build123d.Box(1, 2, 3).wrapped
    # Same classes, so shapes pass freely between the two libraries and nupatch's export.
    assert isinstance(box_cq, OCP.TopoDS.TopoDS_Shape) and isinstance(box_bd, OCP.TopoDS.TopoDS_Shape)
    assert type(box_cq).__module__ == type(box_bd).__module__  # one OCP extension module
    assert cadquery.Shape.cast(box_bd).isValid()
    assert md.version("cadquery-ocp").startswith("7.9.3")
