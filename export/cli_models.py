"""``nupatch models``: the sample control meshes shipped with nupatch, and ``--example NAME``.

In an installed wheel the models are the package data ``export.models`` (pyproject maps the
repository's ``models/`` folder there); in a source checkout they are that folder itself.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from patching.errors import NupatchError

__all__ = ["models_dir", "model_names", "example_paths", "add_parser", "run"]


def models_dir() -> Path:
    """The folder that holds the sample ``.obj`` models."""
    try:
        from importlib.resources import files

        folder = Path(str(files("export.models")))
        if any(folder.glob("*.obj")):
            return folder
    except (ModuleNotFoundError, TypeError):
        pass
    return Path(__file__).resolve().parent.parent / "models"


def model_names() -> list[str]:
    """The sample models' names (file stems), sorted."""
    return sorted(p.stem for p in models_dir().glob("*.obj"))


def example_paths(names: list[str] | None) -> list[str]:
    """The files of the sample models ``names`` (NupatchError naming the known ones)."""
    paths = []
    for name in names or []:
        path = models_dir() / f"{Path(name).stem}.obj"
        if not path.is_file():
            raise NupatchError(f"no sample model '{name}' (there are: {', '.join(model_names())})", "--example")
        paths.append(str(path))
    return paths


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("models", help="list the sample control meshes shipped with nupatch (for build --example)")
    p.add_argument("--paths", action="store_true", help="print each model's file path too")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    folder = models_dir()
    for name in model_names():
        print(f"{name}\t{folder / (name + '.obj')}" if args.paths else name)
    return 0
