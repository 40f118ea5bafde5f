"""Geometry of point clouds and meshes, below any polynomial: well-spread subsamples and point
spacing (:mod:`~ipfit.geometry.sampling`), the distance engine from query points to bare points,
a contour's segments or a mesh's triangles (:mod:`~ipfit.geometry.distance`, compiled in
:mod:`~ipfit.geometry._distance_kernels`), and mesh geometry: merging split vertices, face and vertex
normals, winding numbers (:mod:`~ipfit.geometry.mesh`).

The public names are in :mod:`ipfit` (``ipfit.winding_number``, ``ipfit.outward_vertices``).
Nothing is re-exported here, in this package as in the others: importing one module of a
package runs its ``__init__`` first, so an ``__init__`` that imported its modules would make
reading a mesh load the distance engine (and ``ipfit export`` load the whole search).
"""
