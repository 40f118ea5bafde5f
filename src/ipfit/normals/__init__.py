"""Normal vectors for point clouds: estimation, consistent orientation and comparison.

:func:`estimate_normals` fits a tangent line/plane to each point's k nearest neighbours
(Hoppe et al. 1992), refitted where those are the wrong sample: along the curve in 2D
(NN-crust neighbours), across the curves of surfaces sampled on distant rings or scan lines
in 3D; :func:`orient_normals` makes the signs consistent by propagation along a
minimum spanning tree of the neighbour graph, seeded at points whose outward direction is
known, so that closed shapes get outward normals. :func:`contour_normals` gives the normals of
an ordered 2D contour, and :func:`normal_agreement` compares two sets of normals.

Modules, in the order a point cloud goes through them:

* :mod:`.local` -- k-nearest neighbourhoods and their batched PCA (normal + flatness), the
  normals' confidence;
* :mod:`.estimate` -- :func:`estimate_normals` and the refits where the nearest neighbours
  mislead (thin parts and tips in 2D, anisotropic sampling in 3D); :func:`contour_normals`;
* :mod:`.poles` -- sparse or uneven 3D samples: the line with the largest empty ball (a local
  Voronoi pole), and the points whose outside a large empty ball shows;
* :mod:`.scale` -- noisy data: per-point neighbourhood size, orientation on a coarser sample;
* :mod:`.orient` -- :func:`orient_normals`: sign propagation on the neighbour graph (and, for
  sparse clouds, the winding number's vote);
* :mod:`.rims` -- dense scans: normals turned outward over thin rims, as a mesh's vertex normals
  are, for the fit (:func:`round_rims`);
* :mod:`.compare` -- :func:`normal_agreement`.
"""

from __future__ import annotations

from .compare import Agreement, normal_agreement
from .estimate import contour_normals, estimate_normals
from .local import DEFAULT_K
from .orient import orient_normals
from .rims import round_rims

__all__ = [
    "DEFAULT_K",
    "estimate_normals",
    "orient_normals",
    "round_rims",
    "contour_normals",
    "normal_agreement",
    "Agreement",
]
