"""Choosing the degree: the degree rules as objects (:mod:`~ipfit.degree.rules`: what is clean,
when to stop, which degree to select), the repair of one degree's stray zero set
(:mod:`~ipfit.degree.repair`), the degree loop (:mod:`~ipfit.degree.loop`), the second
looks of a poor first fit (:mod:`~ipfit.degree.looks`), ``fit_adaptive`` and its result
(:mod:`~ipfit.degree.adaptive`) and the result JSON files it writes and reads (:mod:`~ipfit.degree.results`).

The public names are in :mod:`ipfit` (``ipfit.fit_adaptive``, ``ipfit.DegreeRule``, ...); nothing
is re-exported here (see :mod:`ipfit.geometry`): reading a result file must not load the search.
"""
