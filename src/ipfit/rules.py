"""Degree rules: which of the degrees tried :func:`ipfit.fit_adaptive` selects, and why.

``"paper"`` is Algorithm 1 exactly: stop as soon as the smoothness gains no more than ε and
take the previous degree. ``"geometric"`` is the same rule restricted to degrees whose zero set
is clean (no spurious component, closed inside the box) when one exists. Every degree also gets
a one-line reason (selected, rejected, not needed, superseded), stored in the result.
"""

from __future__ import annotations

from typing import Sequence

from ._validation import error
from .quality import Quality

__all__ = ["RULES", "select_degree", "select_degree_geometric", "select", "describe_unclean", "explain", "verdict"]

RULES = ("paper", "geometric")


def select_degree(degrees: Sequence[int], smoothness: Sequence[float], epsilon: float = 0.01,
                  complete: bool = True) -> tuple[int, str]:
    """Apply Algorithm 1's stopping rule to a smoothness path.

    Returns ``(index, reason)``: the index into ``degrees`` of the selected degree, and
    ``'criterion'`` (smoothness improved by ≤ ε at the next degree), ``'max_degree'`` (the
    loop reached its last degree) or ``'incomplete'`` (the path ended early, e.g. on Ctrl-C,
    before the rule fired: its last degree is returned).

    >>> select_degree([2, 4, 6, 8], [0.80, 0.90, 0.905, 0.95])
    (1, 'criterion')
    >>> select_degree([2, 4, 6], [0.8, 0.9, 0.95])
    (2, 'max_degree')
    """
    if len(degrees) != len(smoothness) or not degrees:
        raise error("smoothness", "one value per degree", f"{len(smoothness)} values for {len(degrees)} degrees")
    for i in range(1, len(degrees)):
        if smoothness[i] - smoothness[i - 1] <= epsilon:
            return i - 1, "criterion"
    return len(degrees) - 1, ("max_degree" if complete else "incomplete")


def select_degree_geometric(degrees: Sequence[int], smoothness: Sequence[float], clean: Sequence[bool],
                            f_scores: Sequence[float], epsilon: float = 0.01,
                            complete: bool = True) -> tuple[int, str]:
    """The paper's rule, but never a degree whose zero set is not clean when a clean one exists.

    ``clean[i]`` says degree i's zero set has no spurious component and closes inside the
    box. When the paper's choice is not clean, the clean degree with the highest F-score
    (the lowest such degree on ties) is taken, with reason ``'geometric'``.

    >>> select_degree_geometric([2, 4, 6], [0.8, 0.9, 0.905], [True, False, True], [0.7, 0.9, 0.95])
    (2, 'geometric')
    """
    index, reason = select_degree(degrees, smoothness, epsilon, complete)
    if clean[index] or not any(clean):
        return index, reason
    candidates = [i for i in range(len(degrees)) if clean[i]]
    best = max(candidates, key=lambda i: (f_scores[i], -degrees[i]))
    return best, "geometric"


def select(results, rule, epsilon, reason, fixed: bool) -> tuple[int, str]:
    complete = reason != "interrupted"
    if fixed and complete:
        return 0, "fixed"
    smooth = [r.smoothness for r in results]
    degs = [r.degree for r in results]
    if rule == "geometric":
        index, rule_reason = select_degree_geometric(degs, smooth, [r.clean for r in results],
                                                     [r.quality.f_score for r in results], epsilon, complete)
    else:
        index, rule_reason = select_degree(degs, smooth, epsilon, complete=complete)
    return index, (rule_reason if complete else "interrupted")


def describe_unclean(q: Quality) -> str:
    """Why a zero set is not clean, in one phrase (empty when it is clean)."""
    parts = []
    if q.spurious:
        big = max(q.spurious, key=lambda c: c["size"])
        center = ", ".join(f"{v:.3g}" for v in big["center"])
        parts.append(f"{len(q.spurious)} spurious component{'s' if len(q.spurious) > 1 else ''} (largest "
                     f"{100 * big['share']:.1f}% of the zero set, at ({center}), {big['distance']:.3g} from the data)")
    if not q.closed:
        parts.append("not closed inside the box")
    return "; ".join(parts)


def verdict(results, i, index, message, rule, epsilon) -> str:
    """Why degree ``i`` was selected or not, in one line."""
    entry, chosen = results[i], results[index]
    if i == index:
        return "selected: " + message
    if entry.quality is not None and not entry.clean:
        return "rejected: " + describe_unclean(entry.quality)
    if i > index:
        gain = entry.smoothness - results[i - 1].smoothness
        if gain <= epsilon:
            return f"not needed: smoothness gain {gain:.4g} over degree {results[i - 1].degree} <= epsilon {epsilon:g}"
        if rule == "geometric" and chosen.quality is not None:
            return f"clean, but degree {chosen.degree} was selected (F-score {chosen.quality.f_score:.3f})"
        return f"tried after the selected degree {chosen.degree}"
    gain = results[i + 1].smoothness - entry.smoothness
    if gain > epsilon:
        return f"superseded: degree {results[i + 1].degree} gained {gain:.4g} > epsilon {epsilon:g} in smoothness"
    return f"clean, but degree {chosen.degree} was selected"


def explain(results, index, reason, epsilon) -> str:
    chosen = results[index]
    if reason == "fixed":
        return f"fixed degree {chosen.degree}"
    if reason == "interrupted":
        return f"interrupted: degree {chosen.degree} selected among the {len(results)} degrees finished"
    if reason == "criterion":
        nxt = results[index + 1]
        return (f"degree {chosen.degree}: the smoothness gain at degree {nxt.degree} was "
                f"{nxt.smoothness - chosen.smoothness:.4g} <= epsilon = {epsilon:g}")
    if reason == "geometric":
        return (f"degree {chosen.degree}: the clean degree with the highest F-score; the paper's rule chose a degree "
                "whose zero set has spurious components or is not closed")
    return f"degree {chosen.degree}: the last degree tried (the smoothness still improved by more than {epsilon:g})"
