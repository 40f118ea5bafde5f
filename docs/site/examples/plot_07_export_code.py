"""
Export a fit as code
====================

A fitted polynomial is a few numbers; ``to_source`` writes f and its gradient as standalone
source in Python, C, GLSL, LaTeX or SymPy, in Horner form with the data's normalisation folded
in (``ipfit export RESULT.json --to c`` on the command line). Here a quartic fitted to the boot
is exported to Python, run, and checked against the polynomial; the GLSL version is the start
of a ray-marching shader.
"""

import tempfile
from pathlib import Path

import numpy as np

import ipfit

cloud = ipfit.load("boot")
poly = ipfit.fit_3l(cloud.points, cloud.normals, 4)  # a linear fit: quick and deterministic

source = ipfit.to_source(poly, "python")
print(source)

# %%
# Run the exported code: its values and gradients are the polynomial's.
namespace = {}
exec(source, namespace)  # defines f(x, y) and gradient(x, y) on plain floats
x, y = cloud.points[:5].T
values = np.array([namespace["f"](a, b) for a, b in zip(x, y, strict=True)])
print("largest difference from poly(points):", np.abs(values - poly(cloud.points[:5])).max())

# %%
# The other languages, first lines.
for language in ("c", "glsl", "latex"):
    text = ipfit.to_source(poly, language)
    print(f"--- {language} ({len(text.splitlines())} lines)")
    print("\n".join(text.splitlines()[:6]))

# %%
# The JSON result format holds the same polynomial; it reads back exactly.
path = Path(tempfile.mkdtemp()) / "boot-quartic.json"
poly.save(path)
again = ipfit.ImplicitPolynomial.load(path)
same = np.array_equal(again.coefficients, poly.coefficients) and np.array_equal(
    again(cloud.points), poly(cloud.points))
print("read back exactly:", same)
