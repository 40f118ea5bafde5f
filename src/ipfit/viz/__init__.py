"""Seeing a fit: matplotlib figures (:mod:`~ipfit.viz.plotting`; functions take and return ``ax``)
and the self-contained interactive plotly page (:mod:`~ipfit.viz.viewer`).

Nothing is re-exported here: the two use different optional libraries, and importing one must
not load the other.
"""
