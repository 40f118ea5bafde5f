"""Interactive views of a fit: one self-contained HTML page per result (plotly).

The page holds one plotly figure: on the left the data and the zero set of every degree
tried (a rotatable 3D scene, or pannable 2D axes), a slider that switches the degree shown,
the spurious components of each zero set in their own colour, the points the fit treated
as outliers (the result's ``outliers`` section) as a trace of their own in
:data:`OUTLIER_COLOR` and, behind a legend click, the normals as short segments; on the
right why the degree was selected, the per-degree table and the smoothness (and F-score)
against the degree. Hovering a data point shows its
index and the first-order distance |f| / ‖∇f‖ at the degree shown.

plotly's JavaScript is inlined, so the file works offline. Meshes are decimated for display
(:func:`decimate`, vertex clustering) to keep the page small; the table's measures come from
the result, not from the decimated meshes.

:func:`result_figure` builds the figure, :func:`to_html` its HTML (a whole page, or a
``<div>`` for notebooks), :func:`write_html` writes the page atomically. plotly is an
optional dependency (``pip install 'ipfit[viewer]'``), imported only here.

Modules: ``figure`` (the plotly figure), ``geometry`` (decimation, spurious components),
``pages`` (the HTML around figures, and the index page linking several viewers).

>>> from ipfit.datasets import synthetic
>>> shape = synthetic.circle(64)
>>> fig = result_figure(shape.polynomial, points=shape.points)
>>> [t.name for t in fig.data][:2]
['data points', 'degree 2']
"""

from __future__ import annotations

from .figure import (
                     CURRENT_ROW,
                     CURVE_COLOR,
                     MAX_FACES,
                     MAX_POINTS,
                     OUTLIER_COLOR,
                     REASONS,
                     SPURIOUS_COLOR,
                     SURFACE_COLOR,
                     result_figure,
)
from .geometry import decimate, spurious_flags
from .pages import PLOTLY_SCRIPT, index_page, page, to_html, write_html, write_plotly_script

__all__ = ["result_figure", "to_html", "write_html", "write_plotly_script", "PLOTLY_SCRIPT", "index_page", "decimate",
           "spurious_flags", "page", "MAX_FACES",
           "MAX_POINTS", "OUTLIER_COLOR", "REASONS", "SPURIOUS_COLOR", "SURFACE_COLOR", "CURVE_COLOR", "CURRENT_ROW"]
