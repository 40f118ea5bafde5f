"""
The paper's pipeline
====================

``ipfit fit --paper`` runs the method exactly as Interian et al. (2017) describe it: DE with
the paper's parameters on the paper's distance, in the raw coefficients, on every point,
started from the classic and 3L fits, and Algorithm 1 (the smoothness rule) to stop. The
recommended pipeline adds a far-field term against stray sheets, the L-BFGS polish, a
subsampled search and the capture rule. This example runs both on the butterfly contour and
compares their zero sets.

The paper's search runs 500 DE iterations per degree; to stay quick here it runs 60
(``PAPER.replace(iterations=60)``), which is no longer the exact pipeline: drop the
``replace`` for it.
"""

import ipfit

cloud = ipfit.load("butterfly")
paper_options = ipfit.PAPER.replace(iterations=60)
paper = ipfit.fit_adaptive(cloud, method=ipfit.PAPER_METHOD, options=paper_options, rule=ipfit.PAPER_RULE,
                           outliers="none", max_degree=6, rng=0)
recommended = ipfit.fit_adaptive(cloud, max_degree=6, rng=0)

for name, result in (("paper", paper), ("recommended", recommended)):
    q = ipfit.quality(result.polynomial, cloud, ordered_contour=True)
    print(f"{name:12s} degree {result.selected_degree}, F-score {q.f_score:.3f}, "
          f"spurious components {q.n_spurious}, {sum(d.seconds for d in result.degrees):.1f} s")

# %%
# The paper's degrees: Algorithm 1 looks at the smoothness alone, and nothing keeps the zero
# set from growing spurious components away from the data (drawn in red when there are any).
fig_paper = ipfit.plot_result(paper, cloud.points, title="the paper's pipeline (60 DE iterations)")

# %%
# The recommended pipeline on the same data.
fig_recommended = ipfit.plot_result(recommended, cloud.points, title="the recommended pipeline")
