"""The shape of the packages: data flows one way, no import cycles, no private names taken
from another module, no OpenCASCADE in ``patching``.

The import graph is read from the source (``ast``), with every import counted, also those
inside functions (a lazy import is still a dependency)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from tests.conftest import REPO

PACKAGES = ("patching", "export")
#: The stages of ``patching`` in the order the data flows; a module may import only from its
#: own stage, earlier stages and the shared leaves.
STAGES = (
    "mesh", "topology", "rules", "subdivision", "loop", "shading", "curves",
    "extraordinary", "operator", "evaluation", "fitting", "toolpath",
)
#: Leaf modules every stage may use: they import nothing of the stages.
LEAVES = ("patching.errors", "patching.options", "patching.bernstein", "patching.surface", "patching.util", "patching.validation")


def modules() -> dict[str, Path]:
    found = {}
    for package in PACKAGES:
        for path in sorted((REPO / package).rglob("*.py")):
            parts = path.relative_to(REPO).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            found[name] = path
    return found


def imports(name: str, path: Path) -> list[tuple[str, list[str], int]]:
    """(module imported, names imported, line) for every import in the file, relative ones
    resolved."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    is_package = path.name == "__init__.py"
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(alias.name, [], node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if is_package else name.split(".")[:-1]
                base = base[: len(base) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            out.append((module, [a.name for a in node.names], node.lineno))
    return out


def project_target(module: str, names: list[str], known: dict[str, Path]) -> list[str]:
    """The project modules an import statement depends on (a submodule imported by name counts)."""
    targets = []
    if module in known:
        targets.append(module)
    for n in names:
        if f"{module}.{n}" in known:
            targets.append(f"{module}.{n}")
    if not targets:
        parts = module.split(".")
        while parts and ".".join(parts) not in known:
            parts.pop()
        if parts and parts[0] in PACKAGES:
            targets.append(".".join(parts))
    return targets


def graph() -> dict[str, set[str]]:
    known = modules()
    edges = {m: set() for m in known}
    for name, path in known.items():
        for module, names, _ in imports(name, path):
            for target in project_target(module, names, known):
                if target != name:
                    edges[name].add(target)
    return edges


def test_no_import_cycle_among_modules():
    """Tarjan's strongly connected components over module -> module imports: every component
    is a single module.  A package's ``__init__`` re-exporting its own modules is not a cycle
    (the modules do not import their package), so it counts like any module."""
    edges = graph()
    index, low, stack, on_stack, cycles, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    assert cycles == []


def stage_of(module: str) -> int | None:
    parts = module.split(".")
    if parts[0] != "patching" or len(parts) < 2:
        return None
    return STAGES.index(parts[1]) if parts[1] in STAGES else None


def test_patching_stages_import_only_earlier_stages():
    """mesh -> topology -> rules -> subdivision (Catmull-Clark; Loop, shading) -> curves ->
    extraordinary -> operator -> evaluation -> fitting, tool paths: no stage imports a later
    one, and ``patching`` never imports ``export``."""
    wrong = []
    for source, targets in graph().items():
        if not source.startswith("patching"):
            continue
        for target in targets:
            if target.startswith("export"):
                wrong.append((source, target))
            s, t = stage_of(source), stage_of(target)
            if s is not None and t is not None and t > s:
                wrong.append((source, target))
            if any(source == leaf or source.startswith(leaf + ".") for leaf in LEAVES) and t is not None:
                wrong.append((source, target))
    assert wrong == []


def subpackage(module: str) -> str:
    """``patching.<stage>`` for a module inside a stage's sub-package, else the module itself
    (``export`` is flat: its modules share no private names)."""
    parts = module.split(".")
    return ".".join(parts[:2]) if parts[0] == "patching" and len(parts) > 2 else module


def test_no_private_name_is_imported_from_another_sub_package():
    """``from X import _name`` only within one sub-package (its modules share their helpers)."""
    known = modules()
    wrong = []
    for name, path in known.items():
        for module, names, line in imports(name, path):
            if not module.split(".")[0] in PACKAGES:
                continue
            for n in names:
                if n.startswith("_") and not n.startswith("__") and subpackage(name) != subpackage(module):
                    wrong.append(f"{path.relative_to(REPO)}:{line} imports {n} from {module}")
    assert wrong == []


def test_patching_imports_no_opencascade_or_cad_library():
    """Geometry stays pure numpy/scipy: no OCP, OCC, cadquery, build123d, trimesh or VTK import
    anywhere in ``patching`` (lazy imports included)."""
    forbidden = ("OCP", "OCC", "cadquery", "build123d", "trimesh", "vtk", "matplotlib")
    wrong = []
    for name, path in modules().items():
        if not name.startswith("patching"):
            continue
        for module, _, line in imports(name, path):
            if module.split(".")[0] in forbidden:
                wrong.append(f"{path.relative_to(REPO)}:{line} imports {module}")
    assert wrong == []


@pytest.mark.parametrize("package", PACKAGES)
def test_the_graph_sees_every_module(package):
    """The checks above read every module: the walk finds the sub-packages' modules too (a
    test that read nothing would pass vacuously)."""
    found = [m for m in modules() if m.startswith(package)]
    assert len(found) >= (20 if package == "patching" else 10)
    assert any(graph()[m] for m in found)


def test_the_package_metadata_ships_every_sub_package():
    """pyproject's package list names every directory of ``patching`` and ``export`` that holds
    an ``__init__.py``: a wheel without ``patching.operator`` would install and fail at import."""
    import tomllib

    shipped = set(tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    present = {".".join(p.parent.relative_to(REPO).parts) for pkg in PACKAGES for p in (REPO / pkg).rglob("__init__.py")}
    assert present and present <= shipped
