"""Inside and outside of triangle meshes: generalized winding numbers.

The code lives with the rest of the mesh geometry in :mod:`ipfit.io.mesh`; this module keeps
the name ``ipfit.solid`` working.
"""

from .io.mesh import DEFAULT_STEP_FRACTION, outward_vertices, winding_number

__all__ = ["winding_number", "outward_vertices", "DEFAULT_STEP_FRACTION"]
