"""Free-form surfaces and their sections: Ferguson patches (seed 000), NURBS (splipy), and the
contours of a surface at a Z level (shapely).
"""

from planning.surface.contours import SectionMaker
from planning.surface.ferguson import FergusonSurface
from planning.surface.nurbs import NurbsSurface

__all__ = ["FergusonSurface", "NurbsSurface", "SectionMaker"]
