"""The options of a build, as one frozen value validated once (OpenSubdiv's ``sdc/options.h``).

Every entry point (``patching.build_operator``, ``patching.build``, the command line,
``export.to_build123d`` / ``to_cadquery``) takes a ``BuildOptions``, or the same fields as
keywords, validated here once, and passes it on by value.  The choices are defined here
only: the command line and the deeper modules take them from ``CHOICES``.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Any, Literal, Mapping

from patching.errors import OptionError

__all__ = ["BuildOptions", "CHOICES", "METHODS", "ANGLES", "ANCHORS", "INTERIORS", "G1_SOLVES", "REFINEMENTS", "EIGEN_ANGLES"]

#: The construction at EPs: [FSLYJ]'s (default), or the T-spline baseline of [SSEL13] (its
#: [32]: the extraction's own face points, no auxiliary anchors; uniform angles; the G1
#: perturbation by fairing, ``extraordinary.t_spline``).  "t-spline" fixes angles, anchors and
#: the G1 solve, so those must stay at their defaults (angles may also say "uniform").
METHODS = ("fslyj", "t-spline")

#: Angle configuration at EPs: [FSLYJ] sec. 3.3's optimised angles (default), its heuristic
#: default angles, or 2 pi / n (the T-spline baseline of [SSEL13]).
ANGLES = ("optimized", "default", "uniform")
#: Placement of the auxiliary control points: [FSLYJ] sec. 3.5's eigen-polyhedron rule
#: (default), the extraction's own face points, thin-plate fairing ([FSLYJ] Fig. 16c), or
#: least squares against the non-uniform subdivision's limit surface ([FSLYJ] Fig. 17).
ANCHORS = ("eigen-polyhedron", "extraction", "faired", "limit-fit")
#: Angles of the eigen-polyhedron that places the anchors' limit point and tangent plane
#: ([FSLYJ] sec. 3.5): 2 pi / n ([LFS16], default) or [ZTL]'s modified angles (eq. (10)), the
#: choice ``subdivide --angles`` offers for the subdivision rules.
EIGEN_ANGLES = ("standard", "modified")
#: The four inner coefficients of a quintic patch: kept at the degree-elevated extraction
#: (default), or [FSLYJ] sec. 3.4's cubic iso-curve rule (f_1, f_2).
INTERIORS = ("extraction", "cubic-isocurves")
#: How the G1 unknowns of EPs joined by spokes are set: one joint fairing solve per cluster
#: (default, ``extraordinary.cluster_fairing``), or [FSLYJ] sec. 3.4's per-EP steps.
G1_SOLVES = ("joint", "seed")
#: How semi-sharp tags are refined before patching: "auto" (adaptive beyond a face budget,
#: ``operator.refinement``) or "global" (every face, so that the patches cover one mesh).
REFINEMENTS = ("auto", "global")

CHOICES: Mapping[str, tuple[str, ...]] = {
    "method": METHODS,
    "angles": ANGLES,
    "anchors": ANCHORS,
    "interior": INTERIORS,
    "g1_solve": G1_SOLVES,
    "refinement": REFINEMENTS,
    "eigen_angles": EIGEN_ANGLES,
}


@dataclass(frozen=True)
class BuildOptions:
    """What a build may choose; each field one of ``CHOICES[field]`` (OptionError otherwise)."""

    angles: Literal["optimized", "default", "uniform"] = "optimized"
    anchors: Literal["eigen-polyhedron", "extraction", "faired", "limit-fit"] = "eigen-polyhedron"
    interior: Literal["extraction", "cubic-isocurves"] = "extraction"
    g1_solve: Literal["joint", "seed"] = "joint"
    refinement: Literal["auto", "global"] = "auto"
    method: Literal["fslyj", "t-spline"] = "fslyj"
    eigen_angles: Literal["standard", "modified"] = "standard"

    def __post_init__(self) -> None:
        for name, choices in CHOICES.items():
            value = getattr(self, name)
            if not isinstance(value, str) or value not in choices:
                raise OptionError(f"{name} must be one of {', '.join(choices)}, not {value!r}", name)
        if self.method == "t-spline":
            fixed = {"angles": ("optimized", "uniform"), "anchors": ("eigen-polyhedron",), "g1_solve": ("joint",), "eigen_angles": ("standard",)}
            for name, allowed in fixed.items():
                if getattr(self, name) not in allowed:
                    raise OptionError(
                        f"method t-spline fixes {name} ([SSEL13]'s construction); leave {name} at its "
                        f"default, not {getattr(self, name)!r}",
                        name,
                    )

    @classmethod
    def of(cls, options: "BuildOptions | None" = None, **overrides: Any) -> "BuildOptions":
        """``options`` (default: the defaults) with the keyword ``overrides`` that are not None;
        an unknown keyword is an OptionError naming it."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(overrides) - known)
        if unknown:
            raise OptionError(f"unknown build option {unknown[0]!r} (options: {', '.join(sorted(known))})", unknown[0])
        if options is not None and not isinstance(options, BuildOptions):
            raise OptionError(f"options must be a BuildOptions, not {type(options).__name__}", "options")
        given = {k: v for k, v in overrides.items() if v is not None}
        return replace(options, **given) if options is not None else cls(**given)
