"""
Fit every shape of a folder
===========================

``ipfit.fit_many`` (``ipfit batch`` on the command line) fits many shapes on a Dask cluster:
an embedded one of local processes, an existing one by its address, or a notebook's own
client. It writes ``NAME.json`` per shape and ``summary.csv`` into the output folder, skips
the shapes already fitted with the same settings (re-run it to resume), and turns a shape that
fails into a row with its error. It needs the ``dask`` extra (``pip install 'ipfit[dask]'``).

Here a folder of four point files (two generated contours and two surfaces, written with
``ipfit.write_points``) is fitted by one worker process.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

import ipfit
from ipfit.datasets import collection

folder = Path(tempfile.mkdtemp())
(folder / "shapes").mkdir()
shapes = collection(4, seed=3)  # star, blob, superquadric, torus
for shape in shapes:
    ipfit.write_points(folder / "shapes" / f"{shape.name}.ply", shape.points, shape.normals)
print(sorted(p.name for p in (folder / "shapes").iterdir()))

batch = ipfit.fit_many([folder / "shapes"], output=folder / "results", workers=1, max_degree=4)
print(batch.counts(), f"in {batch.seconds:.1f} s")
for row in batch.rows:
    print(f"{row['name']:18s} {row['dim']}D  degree {row['selected_degree']}  F-score {row['f_score']:.3f}")
print(sorted(p.name for p in (folder / "results").iterdir()))

# %%
# Each result file reads back as a polynomial; the contours with their fits:
fig, axes = plt.subplots(1, 2, figsize=(8, 4))
for ax, shape in zip(axes, shapes[:2], strict=True):
    poly = ipfit.ImplicitPolynomial.load(folder / "results" / f"{shape.name}.json")
    ipfit.plot_curve(poly, shape.points, ax=ax)
    ax.set_title(shape.name)
plt.show()
