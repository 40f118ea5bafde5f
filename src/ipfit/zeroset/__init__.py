"""The zero set of a fitted polynomial: extraction by marching squares or cubes on a grid
(:mod:`~ipfit.zeroset.extract`), its quality against the data (:mod:`~ipfit.zeroset.quality`:
recall, precision, F-score, spurious components), trimming it to the data
(:mod:`~ipfit.zeroset.trim`) and writing it as a mesh or curves (:mod:`~ipfit.zeroset.export`).

The public names are in :mod:`ipfit` (``ipfit.extract_zero_set``, ``ipfit.quality``, ...); nothing
is re-exported here (see :mod:`ipfit.geometry`).
"""
