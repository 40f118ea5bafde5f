"""Fitting a polynomial of one degree: the linear fits and their one registry of methods
(:mod:`~ipfit.fitting.linear`), fits of clouds bigger than memory (:mod:`~ipfit.fitting.chunked`),
the paper's measures and objective (:mod:`~ipfit.fitting.objective`, compiled in
:mod:`~ipfit.fitting._objective_kernels`) with its far-field term (:mod:`~ipfit.fitting.farfield`),
every search setting (:mod:`~ipfit.fitting.options`: ``SearchOptions`` and the presets), the start
fits of a search (:mod:`~ipfit.fitting.starts`) and the search itself, start fits → DE/PSO →
polish (:mod:`~ipfit.fitting.refine`; the solvers are :mod:`ipfit.optimize`).

The public names are in :mod:`ipfit` (``ipfit.fit_linear``, ``ipfit.refine``, ``ipfit.SearchOptions``,
...); nothing is re-exported here (see :mod:`ipfit.geometry`).
"""
