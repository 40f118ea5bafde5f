"""
Fit a mesh
==========

A mesh file brings its vertices, its faces and, from the faces, area-weighted normals; the
faces also let the quality measure (F-score) compare the zero set with the surface itself
rather than with bare points. The bundled ``apple`` is a small scanned mesh.
"""

import ipfit

cloud = ipfit.load("apple")
print(cloud.points.shape, "vertices,", len(cloud.faces), "faces; normals from:", cloud.normals_source)

# In 3D the defaults go up to degree 8; degree 4 keeps the example quick.
result = ipfit.fit_adaptive(cloud, max_degree=4, rng=0)
print(result.message)
for degree in result.degrees:
    q = degree.quality
    print(f"degree {degree.degree}: F-score {q.f_score:.3f}, spurious parts {q.n_spurious}")

# %%
# Each degree's zero set, extracted by marching cubes, beside the data.
fig = ipfit.plot_result(result, cloud.points, faces=cloud.faces)

# %%
# The zero set as a mesh, ready to save as PLY, OBJ or STL (``ipfit mesh`` on the command
# line, or ``ipfit.save_zero_set``).
zero_set = ipfit.extract_zero_set(result.polynomial, points=cloud.points)
print(zero_set)
