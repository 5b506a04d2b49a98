"""Subdivision rules only: masks (weights) over a vertex's neighbourhood, no mesh, no
positions (OpenSubdiv's ``sdc``).  ``catmark``: non-uniform Catmull-Clark curve and tagged
vertex rules ([TLC] sec. 4, [BLZ00]); ``eigen_polyhedron``: the local eigen-polyhedron rules
at extraordinary vertices ([LFS16], [TLC] sec. 3, [ZTL]); ``crease``: how sharpness decays a
step (uniform or Chaikin creasing, [OSD] ``sdc/crease.cpp``), shared by Catmull-Clark
(``subdivision``) and Loop (``loop``).  A new scheme (Loop) is a new module here, used by its
own refinement step in ``subdivision``."""
