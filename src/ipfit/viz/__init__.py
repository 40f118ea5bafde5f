"""Seeing a fit: matplotlib figures (:mod:`~ipfit.viz.plotting`; functions take and return ``ax``)
and the self-contained interactive plotly page (:mod:`~ipfit.viz.viewer`).

The public names are in :mod:`ipfit` (``ipfit.plot_result``, ...); nothing is re-exported here
(see :mod:`ipfit.geometry`): the figures and the viewer use different libraries.
"""
