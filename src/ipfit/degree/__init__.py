"""Choosing the degree: the degree rules as objects (:mod:`~ipfit.degree.rules`: what is clean,
when to stop, which degree to select), the repair of one degree's stray zero set
(:mod:`~ipfit.degree.repair`), the degree loop (:mod:`~ipfit.degree.adaptive`: ``fit_adaptive``
and its results) and the result JSON files it writes and reads (:mod:`~ipfit.degree.results`).

The function ``repair`` is not re-exported here: ``ipfit.degree.repair`` is its module.
"""

from .adaptive import AdaptiveResult, DegreeResult, fit_adaptive, select_degree
from .results import load_result, result_view, write_result
from .rules import RULES, DegreeRule, get_rule

__all__ = [
    "fit_adaptive",
    "AdaptiveResult",
    "DegreeResult",
    "select_degree",
    "DegreeRule",
    "RULES",
    "get_rule",
    "load_result",
    "result_view",
    "write_result",
]
