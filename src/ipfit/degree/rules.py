"""Degree rules: which of the degrees tried :func:`ipfit.fit_adaptive` selects, and why.

``"capture"`` (the default) stops when the shape is captured and selects on the geometry:

* **keep going** while a degree still gains substantially in any of: smoothness (more than ε),
  F-score or recall (more than :data:`GAIN` over the best so far), the paper's distance or the
  mean data-to-zero-set distance (a relative drop of more than :data:`DISTANCE_GAIN`);
* **stop** when a clean degree reaches F ≥ 1 − :data:`TOLERANCE` (captured: no higher degree
  could then be selected, see below), or after :data:`PATIENCE` degrees in a row without a
  substantial gain (look-ahead), or at the maximum degree; beyond :data:`CAPTURE_USUAL_DEGREE`
  (14 in 2D, 8 in 3D) a degree is fitted only when the one before it raised the best clean
  F-score by more than :data:`GAIN` and left it below :data:`EXTEND_BELOW` (0.98 in 2D, 0.95 in
  3D): thin parts need degrees 10 and 12 in 3D, 16 to 20 in 2D, which cost several times the
  usual top degree and rarely pay elsewhere (docs/quality-3d.md, docs/max-degree-2d.md);
* **select** the lowest clean degree whose F-score is within :data:`TOLERANCE` of the best
  clean F-score, so simple shapes keep low degrees and a degree that bulges (lower precision,
  hence lower F) is not preferred over one that does not. A clean degree whose F-score is
  below :data:`MISSES_BELOW` misses the data and does not count (a closed blob beside the
  points is no fit). With no clean degree that follows the data, the highest F-score (and
  ``success`` is False when a clean degree was passed over);
* **prefer the data's topology** where the data tells it with confidence: when that choice has
  another, the lowest degree of the band (within :data:`TOLERANCE` of the best clean F-score)
  that has the data's topology, as fitted or repaired to it, is selected instead
  (:meth:`CaptureRule.settle`); with none, the degree of the data's topology with the
  highest F-score within :data:`TOPOLOGY_BAND` of the best; else the choice stays and its
  topology is reported.

*Clean* (:func:`is_clean`) means no spurious component that matters, no open piece near
the data, and for the ``"topology"`` rule the data's topology where the data tells it with
confidence (an ordered contour or silhouette, a closed mesh: :mod:`ipfit.zeroset.topology`; the
same loops and nesting in 2D, components and genus in 3D, specks left out): a *speck* (:func:`is_speck`: a spurious
component shorter than τ/2 in 2D, smaller than τ²/4 in area in 3D, that comes within
:data:`SPECK_REACH` τ of the data; τ is the quality tolerance, 2 % of the box diagonal) is a
fragment of a thin part at the measurement's resolution and does not
count, while a small oval out in empty space does; a zero set counts as closed when every piece
near the data closes in the box.

``"paper"`` is Algorithm 1 exactly: stop as soon as the smoothness gains no more than ε and
take the previous degree. ``"geometric"`` (the rule before ``"capture"``) is the same rule
restricted to degrees whose zero set is strictly clean (no spurious component, closed inside
the box) when one exists. ``"topology"`` is the capture rule that holds the data's topology at
any cost in F-score (:class:`TopologyRule`). Every degree also gets a one-line reason (selected, rejected, not
needed, superseded), stored in the result.

Each rule is one object, a :class:`DegreeRule` (:data:`CAPTURE`, :data:`GEOMETRIC`,
:data:`PAPER`), registered by name in :data:`RULES`; :func:`get_rule` turns a name (what the
public API and the command line accept) into its object. The adaptive loop
(:func:`ipfit.fit_adaptive`) asks the rule everything rule-specific: whether to measure, how far
to go, whether a degree is clean or needs a repair, when to stop, which degree to select and
the texts. A new rule is a subclass of :class:`DegreeRule`, passed as ``rule=`` (see its
protocol); registering it in :data:`RULES` makes its name accepted too.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, TypeGuard

from .._utils.validation import check_choice, error
from ..zeroset.quality import Quality
from ..zeroset.topology import SPECK_REACH, describe_mismatch, is_speck

if TYPE_CHECKING:
    from .adaptive import DegreeResult

__all__ = ["RULES", "DegreeRule", "CaptureRule", "GeometricRule", "PaperRule", "TopologyRule", "CAPTURE", "GEOMETRIC",
           "PAPER", "TOPOLOGY",
           "get_rule", "select_degree", "select_degree_geometric", "select_degree_capture", "gains", "capture_stop",
           "is_clean", "describe_unclean", "topology_differs", "GAIN", "DISTANCE_GAIN", "PATIENCE", "TOLERANCE",
           "is_speck", "SPECK_REACH", "DEFAULT_MAX_DEGREE", "CAPTURE_MAX_DEGREE",
           "CAPTURE_USUAL_DEGREE", "EXTEND_BELOW", "PRECISION_TARGET", "REPAIR_RECALL",
           "MISSING_RECALL", "MISSES_BELOW", "TOPOLOGY_BAND"]

#: Maximum degree tried by default, per dimension (the paper: degrees 2 to 10 are the norm).
DEFAULT_MAX_DEGREE = {2: 10, 3: 8}
#: ... and with the capture rule, which stops by itself once the shape is captured and so can
#: afford the higher degrees that thin or detailed contours need (docs/degree-rule.md,
#: docs/max-degree-2d.md), and that thin parts of 3D shapes need (docs/quality-3d.md), where
#: the data have :attr:`CaptureRule.points_per_coefficient` points per coefficient.
CAPTURE_MAX_DEGREE = {2: 20, 3: 12}
#: The capture rule's degrees above this one (per dimension) are fitted only while each degree
#: gains F-score and the best is still below :data:`EXTEND_BELOW` (see :func:`capture_stop`).
#: Up to it in 2D, every degree the look-ahead asks for: allowed beyond it, the same look-ahead
#: took 27 of the 140 MPEG-7 development contours to degree 16 and 3 of them to another
#: topology (docs/max-degree-2d-16.md).
CAPTURE_USUAL_DEGREE = {2: 14, 3: 8}
#: See :data:`CAPTURE_USUAL_DEGREE`: a shape fitted this well (per dimension) gains too little from
#: a higher degree to pay for it. Higher in 2D, where degrees 16-20 cost seconds: at 0.98 instead
#: of 0.95 two more outlines (a beetle, the bundled butterfly) go on, each gaining 0.02, and none
#: loses (docs/max-degree-2d.md); a 3D degree above 8 costs two to four times degree 8.
EXTEND_BELOW = {2: 0.98, 3: 0.95}

#: capture rule: the smallest F-score or recall gain (over the best so far) worth another degree.
GAIN = 0.01
#: capture rule: the smallest relative drop of the paper's distance or of the mean
#: data-to-zero-set distance worth another degree.
DISTANCE_GAIN = 0.25
#: capture rule: degrees in a row without a substantial gain before the loop stops.
PATIENCE = 2
#: capture rule: the lowest clean degree within this F-score of the best clean one is selected.
TOLERANCE = 0.01
#: capture rule: a clean degree whose precision is below PRECISION_TARGET while its recall is at
#: least REPAIR_RECALL is repaired too: the zero set reaches the data but also bulges away from
#: it. A degree that misses the data as well is too low, not defective.
PRECISION_TARGET = 0.95
REPAIR_RECALL = 0.9
#: capture rule, 3D: a clean, precise degree whose recall is below this gets a round for the
#: surface it misses (:meth:`CaptureRule.fills_missing`).
MISSING_RECALL = 0.95
#: capture rule: a clean degree whose F-score is below this misses most of the data, and being
#: clean protects nothing then: the selection does not prefer it to a degree that follows the
#: data but is not clean (:func:`select_degree_capture`), nor does the comparison of whole fits
#: in :func:`ipfit.fit_adaptive`. Noisy and sparse 3D clouds of thin shapes end there: the Turk
#: airplane at σ = 0.5 % of the diagonal kept an ellipsoid of F 0.48 on its points over a
#: degree 6 of F 0.89 with one spurious piece (docs/reorient.md).
MISSES_BELOW = 0.5
#: capture rule, per dimension: when no degree within :data:`TOLERANCE` of the best clean
#: F-score has the data's topology (known with confidence), as fitted, repaired to it or one
#: degree beyond the stop, the degree of the data's topology with the highest F-score within
#: this of the best is selected (:meth:`CaptureRule.settle`). A solid in pieces or with a handle
#: the data has not, a tail or a leg as a loop of its own, is another shape at any F-score: the
#: cow's legs cut off at degree 8 (F 0.965) are held on at degree 6 (0.934,
#: docs/topology-external.md), the MPEG-7 cattle's legs at 0.985 against 0.999 (docs/topology.md).
#: Beyond it the outline itself is lost for the topology (an MPEG-7 fly whose thin legs join
#: it only at F 0.694 against 0.878).
TOPOLOGY_BAND = {2: 0.04, 3: 0.04}


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


def topology_differs(q: Quality | None) -> bool:
    """Whether a measured zero set's topology differs from the data's, the data's being known
    with confidence (:attr:`ipfit.zeroset.topology.Topology.known`: an ordered contour or a
    silhouette, a closed mesh whose parts do not intersect). A bare cloud's estimate never counts.
    """
    return (q is not None and q.data_topology is not None and q.data_topology.known
            and q.topology_matches is False)


def is_clean(q: Quality | None, *, ignore_specks: bool = True, topology: bool = True) -> TypeGuard[Quality]:
    """Whether a measured zero set is clean: the one definition, parametrised as the rules differ.

    Parameters
    ----------
    q : the degree's :class:`~ipfit.zeroset.quality.Quality`, or None when it was not measured (never clean).
    ignore_specks : True (the capture rule): a non-empty zero set, every spurious component a
        speck (:func:`is_speck`) and every piece *near the data* closed inside the box. False
        (the geometric rule): no spurious component at all and the *whole* zero set closed
        inside the box.
    topology : also the data's topology when it is known with confidence
        (:func:`topology_differs`); the "topology" rule checks it.

    Returns
    -------
    bool

    Examples
    --------
    >>> from ipfit.datasets import synthetic
    >>> from ipfit.zeroset.quality import quality
    >>> shape = synthetic.circle()
    >>> is_clean(quality(shape.polynomial, shape.points))
    True
    """
    if q is None or (topology and topology_differs(q)):
        return False
    if not ignore_specks:
        return q.n_spurious == 0 and bool(q.closed)
    if q.n_components == 0:
        return False
    return all(is_speck(c, q.tau) for c in q.spurious) and q.n_open == 0


def _clean_f(entry, topology: bool = True) -> float | None:
    return entry.quality.f_score if is_clean(entry.quality, topology=topology) else None


def gains(entries, i: int, epsilon: float) -> list[str]:
    """The substantial gains of ``entries[i]`` over the degrees before it, in words (capture rule).

    ``entries`` are per-degree results with ``smoothness``, ``distance`` and ``quality``.
    """
    if i == 0:
        return []
    entry, before = entries[i], entries[:i]
    out = []
    smooth = entry.smoothness - before[-1].smoothness
    if smooth > epsilon:
        out.append(f"smoothness +{smooth:.3g}")
    q = entry.quality
    measured = [e.quality for e in before if e.quality is not None]
    if q is not None and measured:
        for name, key in (("F-score", "f_score"), ("recall", "recall")):
            gain = getattr(q, key) - max(getattr(m, key) for m in measured)
            if gain > GAIN:
                out.append(f"{name} +{gain:.3g}")
        previous = before[-1].quality
        if previous is not None and previous.data_to_zero_set > 0:
            drop = 1 - q.data_to_zero_set / previous.data_to_zero_set
            if drop > DISTANCE_GAIN:
                out.append(f"data-to-zero-set distance -{100 * drop:.0f}%")
    if before[-1].distance > 0:
        drop = 1 - entry.distance / before[-1].distance
        if drop > DISTANCE_GAIN:
            out.append(f"paper's distance -{100 * drop:.0f}%")
    return out


def capture_stop(entries, epsilon: float, usual_degrees: Mapping[int, int] = CAPTURE_USUAL_DEGREE) -> str | None:
    """Whether the capture rule's loop stops after the last of ``entries``: 'captured' (a clean
    degree has F ≥ 1 − TOLERANCE, so no higher degree could be selected), 'flattened'
    (:data:`PATIENCE` degrees in a row without a substantial gain), 'no_f_gain' (the last degree
    is ``usual_degrees[dim]`` (:data:`CAPTURE_USUAL_DEGREE`) or above and did not raise the best
    clean F-score by more than :data:`GAIN`, or raised it to ``EXTEND_BELOW[dim]`` or more; clean
    here apart from the topology) or None (go on)."""
    clean_f = list(map(_clean_f, entries))
    if any(f is not None and f >= 1 - TOLERANCE for f in clean_f):
        return "captured"
    if len(entries) > PATIENCE and not any(gains(entries, i, epsilon)
                                           for i in range(len(entries) - PATIENCE, len(entries))):
        return "flattened"
    last = entries[-1]
    usual = usual_degrees.get(last.polynomial.dim)
    if usual is not None and last.degree >= usual:
        # Whether a higher degree still pays is a question of F-score: the topology is the
        # selection's (CaptureRule.settle). Octopus and fly outlines of the MPEG-7 development
        # set have another topology than one loop at degree 14, and degree 16-18 raise their
        # F-score from 0.85-0.88 to 0.92-0.93 (docs/max-degree-2d.md).
        shape_f = [_clean_f(entry, topology=False) for entry in entries]
        before = max((f for f in shape_f[:-1] if f is not None), default=0.0)
        if shape_f[-1] is None or shape_f[-1] - before <= GAIN or shape_f[-1] >= EXTEND_BELOW[last.polynomial.dim]:
            return "no_f_gain"
    return None


def select_degree_capture(degrees: Sequence[int], f_scores: Sequence[float], clean: Sequence[bool]) -> int:
    """The capture rule's choice: the lowest clean degree whose F-score is within
    :data:`TOLERANCE` of the best clean one, among the clean degrees that follow the data
    (F-score at least :data:`MISSES_BELOW`); with none, the same among all degrees (the lowest
    within :data:`TOLERANCE` of the best F-score: a higher degree must gain more than that to be
    worth its unclean zero set too).

    >>> select_degree_capture([2, 4, 6, 8], [0.70, 0.951, 0.958, 0.99], [True, True, True, False])
    1
    >>> select_degree_capture([2, 4, 6], [0.48, 0.89, 0.78], [True, False, False])
    1
    """
    if len(degrees) != len(f_scores) or len(degrees) != len(clean) or not degrees:
        raise error("f_scores", "one F-score and one clean flag per degree",
                    f"{len(f_scores)} and {len(clean)} for {len(degrees)} degrees")
    pool = [i for i in range(len(degrees)) if clean[i] and f_scores[i] >= MISSES_BELOW] or list(range(len(degrees)))
    best = max(f_scores[i] for i in pool)
    return min((i for i in pool if f_scores[i] >= best - TOLERANCE), key=lambda i: degrees[i])


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
    if topology_differs(q):
        parts.append(describe_mismatch(q.topology, q.data_topology))  # type: ignore[arg-type]
    return "; ".join(parts)


def _measured(entry: DegreeResult) -> Quality:
    """The quality of a degree a ``measured`` rule fitted, which it always has."""
    if entry.quality is None:
        raise ValueError(f"degree {entry.degree}: not measured")  # a bug of ipfit's, not an input error
    return entry.quality


# -- the rules as objects --------------------------------------------------------------------------
class DegreeRule(ABC):
    """A degree rule: what :func:`ipfit.fit_adaptive` asks about the degrees it fits.

    The loop fits degree after degree; after each one it asks :meth:`stop`, and at the end
    :meth:`select` picks a degree, :meth:`explain` says why and :meth:`reason` gives each
    degree's line. A subclass sets the attributes and implements :meth:`stop` and
    :meth:`select`; the other methods have working defaults. Results record the rule by
    :attr:`name`.

    Attributes
    ----------
    name : str
        The rule's name, written in results (``adaptive.rule``) and accepted by
        :func:`get_rule` once the rule is in :data:`RULES`.
    measured : bool
        Whether every degree's zero set is measured (:class:`~ipfit.zeroset.quality.Quality`) and, when
        not clean, repaired; an unmeasured degree has ``quality=None`` and is never clean.
    ignore_specks : bool
        Which definition of clean applies (:func:`is_clean`).
    checks_topology : bool
        Whether a zero set of another topology than the data's (known with confidence) is not
        clean, and the repair tries to fix it (:func:`topology_differs`).
    prefers_topology : bool
        Whether, when the choice has another topology than the data's, :meth:`settle` looks for
        a degree of the data's topology within its tolerance of the best F-score (in 3D, failing
        that, within its :attr:`~CaptureRule.topology_band`), repairing degrees to it (as
        :data:`TOPOLOGY` does) where needed (see :class:`CaptureRule`).
    max_degrees : Mapping[int, int]
        The last degree tried when the caller gives none, per dimension (:meth:`max_degree`).
    points_per_coefficient : int
        Automatic degrees (no ``max_degree`` given) keep at least this many points per
        coefficient.
    """

    name: str = ""
    measured: bool = True
    ignore_specks: bool = False
    checks_topology: bool = False
    prefers_topology: bool = False
    max_degrees: Mapping[int, int] = DEFAULT_MAX_DEGREE
    points_per_coefficient: int = 1

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r}>"

    def max_degree(self, dim: int) -> int:
        """The last degree tried in ``dim`` dimensions when the caller gives no maximum."""
        return self.max_degrees[dim]

    def is_clean(self, quality: Quality | None) -> TypeGuard[Quality]:  # clean: measured
        """Whether a degree's zero set is clean for this rule (:func:`is_clean`)."""
        return is_clean(quality, ignore_specks=self.ignore_specks, topology=self.checks_topology)

    def best_clean_f(self, results: Sequence[DegreeResult]) -> float:
        """The best F-score among the clean degrees of ``results`` (0 when none is clean)."""
        return max((r.quality.f_score for r in results if self.is_clean(r.quality)), default=0.0)

    def is_done(self, entry: DegreeResult, best_f: float = 0.0) -> bool:
        """Nothing left to repair in ``entry`` (:func:`ipfit.degree.repair.repair` stops, or does not
        start); ``best_f`` is the best clean F-score of the degrees before it. Default: clean."""
        return self.is_clean(entry.quality)

    def fills_missing(self, entry: DegreeResult, best_f: float = 0.0) -> bool:
        """Whether ``entry``, done or repaired, gets a round for the data its zero set misses
        (:func:`ipfit.degree.repair.fill_missing`); ``best_f`` as for :meth:`is_done`. Default: no."""
        return False

    @abstractmethod
    def stop(self, results: Sequence[DegreeResult], epsilon: float) -> str | None:
        """Whether the loop stops after the last of ``results``: why in one word (it becomes
        the result's ``reason``), or None to fit the next degree."""

    @abstractmethod
    def select(self, results: Sequence[DegreeResult], epsilon: float, reason: str) -> tuple[int, str]:
        """``(index, reason)``: the index into ``results`` of the selected degree, and the
        result's reason. ``reason`` is how the loop ended: what :meth:`stop` returned,
        ``'max_degree'`` or ``'interrupted'`` (Ctrl-C: ``results`` are the degrees finished)."""

    def settle(self, results: Sequence[DegreeResult], epsilon: float, reason: str,
               variant: Callable[[int], tuple[DegreeResult, DegreeResult | None]] | None = None,
               final: bool = True) -> tuple[list[DegreeResult], int, str]:
        """``(results, index, reason)``: :meth:`select`'s choice, with ``results`` as the loop ends
        them. A rule that :attr:`prefers_topology` may ask ``variant(i)`` for degree ``i`` repaired
        to the data's topology: it returns ``results[i]`` with that repair's rounds recorded, and
        the repaired degree when it is clean and of the data's topology (else None). ``final`` is
        False while the loop decides whether to fit one degree beyond the rule's stop (a choice
        the rule would only make last waits for that degree). Default: the results as they are,
        the choice :meth:`select`'s."""
        return list(results), *self.select(results, epsilon, reason)

    def explain(self, results: Sequence[DegreeResult], index: int, reason: str, epsilon: float) -> str:
        """The result's message: which degree was selected and why, in words."""
        return f"degree {results[index].degree}: selected by the {self.name} rule ({reason})"

    def reason(self, results: Sequence[DegreeResult], i: int, index: int, message: str, epsilon: float) -> str:
        """Why degree ``results[i]`` was selected or not, in one line (``message`` is :meth:`explain`'s)."""
        if i == index:
            return "selected: " + message
        if self.measured and not self.is_clean(results[i].quality):
            return "rejected: " + (describe_unclean(_measured(results[i])) or "empty zero set")
        return f"not selected: degree {results[index].degree} was"

    def success(self, results: Sequence[DegreeResult], index: int) -> bool:
        """Whether the selection succeeded: the selected degree is clean, or none is."""
        return self.is_clean(results[index].quality) or not any(self.is_clean(r.quality) for r in results)


class PaperRule(DegreeRule):
    """Algorithm 1 exactly: stop as soon as the smoothness gains no more than ε, take the
    degree before; nothing is measured."""

    name = "paper"
    measured = False
    checks_topology = False

    def stop(self, results, epsilon):
        if len(results) >= 2 and results[-1].smoothness - results[-2].smoothness <= epsilon:
            return "criterion"
        return None

    def select(self, results, epsilon, reason):
        complete = reason != "interrupted"
        index, rule_reason = self._choose(results, epsilon, complete)
        return index, (rule_reason if complete else "interrupted")

    def _choose(self, results, epsilon, complete: bool) -> tuple[int, str]:
        return select_degree([r.degree for r in results], [r.smoothness for r in results], epsilon,
                             complete=complete)

    def explain(self, results, index, reason, epsilon):
        chosen = results[index]
        if reason == "interrupted":
            return f"interrupted: degree {chosen.degree} selected among the {len(results)} degrees finished"
        if reason == "criterion":
            nxt = results[index + 1]
            return (f"degree {chosen.degree}: the smoothness gain at degree {nxt.degree} was "
                    f"{nxt.smoothness - chosen.smoothness:.4g} <= epsilon = {epsilon:g}")
        return f"degree {chosen.degree}: the last degree tried (the smoothness still improved by more than {epsilon:g})"

    def reason(self, results, i, index, message, epsilon):
        entry, chosen = results[i], results[index]
        if i == index:
            return "selected: " + message
        if entry.quality is not None and not self.is_clean(entry.quality):
            return "rejected: " + describe_unclean(entry.quality)
        if i > index:
            gain = entry.smoothness - results[i - 1].smoothness
            if gain <= epsilon:
                return (f"not needed: smoothness gain {gain:.4g} over degree {results[i - 1].degree} "
                        f"<= epsilon {epsilon:g}")
            if chosen.quality is not None:  # measured: the geometric rule chose on the F-score
                return f"clean, but degree {chosen.degree} was selected (F-score {chosen.quality.f_score:.3f})"
            return f"tried after the selected degree {chosen.degree}"
        gain = results[i + 1].smoothness - entry.smoothness
        if gain > epsilon:
            return f"superseded: degree {results[i + 1].degree} gained {gain:.4g} > epsilon {epsilon:g} in smoothness"
        return f"clean, but degree {chosen.degree} was selected"


class GeometricRule(PaperRule):
    """Algorithm 1 restricted to strictly clean degrees (no spurious component, closed inside the
    box) when one exists: it stops on the criterion only once a clean degree was found, and
    replaces an unclean choice by the clean degree with the best F-score."""

    name = "geometric"
    measured = True

    def stop(self, results, epsilon):
        stop = super().stop(results, epsilon)
        return stop if stop is None or any(self.is_clean(r.quality) for r in results) else None

    def explain(self, results, index, reason, epsilon):
        if reason == "geometric":
            return (f"degree {results[index].degree}: the clean degree with the highest F-score; the paper's rule "
                    "chose a degree whose zero set has spurious components, is not closed or has another "
                    "topology than the data")
        return super().explain(results, index, reason, epsilon)

    def _choose(self, results, epsilon, complete):
        return select_degree_geometric([r.degree for r in results], [r.smoothness for r in results],
                                       [self.is_clean(r.quality) for r in results],
                                       [r.quality.f_score for r in results], epsilon, complete)


class CaptureRule(DegreeRule):
    """The default rule: go on while a degree gains substantially, stop once the shape is
    captured or :data:`PATIENCE` degrees gain nothing, select the lowest clean degree within
    :data:`TOLERANCE` of the best clean F-score (see the module's notes). Specks do not count.

    The data's topology, where the data tells it with confidence, is preferred at no cost in
    F-score: when the choice above has another topology than the data's, the lowest clean degree
    within :data:`TOLERANCE` of the best clean F-score that has the data's topology, as fitted or
    repaired to it (a neck held inside, a gap outside: the :data:`TOPOLOGY` rule's repair, tried
    on the degrees of that band only, lowest first), is selected instead. Where no such degree
    exists and the loop stopped below its last degree, :func:`~ipfit.fit_adaptive` fits one
    degree more, repaired for the topology at once (set aside, recorded, when it has another
    topology too). Where there is still none, the degree of the data's topology with the highest
    F-score within :attr:`topology_band` (:data:`TOPOLOGY_BAND`) of the best clean one is
    selected (a solid in pieces is another solid, a leg as its own loop another outline);
    otherwise (a thin part that can only join at a greater cost in F-score) the choice stays,
    its topology reported; the ``"topology"`` rule holds the topology at any cost.
    """

    name = "capture"
    ignore_specks = True
    prefers_topology = True
    max_degrees = CAPTURE_MAX_DEGREE
    #: How far below the best clean F-score the data's topology is still preferred, per dimension,
    #: when no degree within the tolerance has it (:data:`TOPOLOGY_BAND`).
    topology_band: Mapping[int, float] = TOPOLOGY_BAND
    #: Degrees above these (per dimension) only while the F-score still rises (:func:`capture_stop`).
    usual_degrees: Mapping[int, int] = CAPTURE_USUAL_DEGREE
    # Near interpolation a fit follows the points and wiggles between them; the capture rule's
    # higher default degrees would get there on small clouds.
    points_per_coefficient = 2

    def is_done(self, entry, best_f=0.0):
        """Clean and precise enough (precision at least :data:`PRECISION_TARGET`), too low a
        degree (recall below :data:`REPAIR_RECALL`: it misses data) or out of the race (even a
        precision of 1 would leave its F-score more than :data:`TOLERANCE` below ``best_f``).
        So a clean degree that bulges away from the data is repaired too."""
        q = entry.quality
        if not self.is_clean(q):
            return False
        if q.precision >= PRECISION_TARGET or q.recall < REPAIR_RECALL:
            return True
        return 2 * q.recall / (1 + q.recall) < best_f - TOLERANCE

    def fills_missing(self, entry, best_f=0.0):
        """3D: a clean degree in the race (F-score within :data:`TOLERANCE` of ``best_f`` or above)
        whose zero set lies on the data (precision at least :data:`PRECISION_TARGET`) but misses
        some of it (recall below :data:`MISSING_RECALL`): a thin part cut short."""
        q = entry.quality
        return (entry.polynomial.dim == 3 and self.is_clean(q) and q.precision >= PRECISION_TARGET
                and q.recall < MISSING_RECALL and q.f_score >= best_f - TOLERANCE)

    def stop(self, results, epsilon):
        return capture_stop(results, epsilon, self.usual_degrees)

    def select(self, results, epsilon, reason):
        index = select_degree_capture([r.degree for r in results], [r.quality.f_score for r in results],
                                      [self.is_clean(r.quality) for r in results])
        return index, reason

    def settle(self, results, epsilon, reason, variant=None, final=True):
        results = list(results)
        index, reason = self.select(results, epsilon, reason)
        chosen = results[index]
        if not self.prefers_topology or variant is None or not self.is_clean(chosen.quality) or \
                not topology_differs(chosen.quality):
            return results, index, reason
        # The choice has another topology than the data's: the lowest degree within the band of
        # the best clean F-score that has the data's, as fitted or repaired to it (repairs only
        # for the degrees of the band, lowest first: each costs a few polishes).
        best = max(r.quality.f_score for r in results if self.is_clean(r.quality))
        for i in sorted(range(len(results)), key=lambda i: results[i].degree):
            candidate = self._of_data_topology(results, i, variant, best - TOLERANCE)
            if candidate is not None:
                results[i] = candidate
                return results, i, reason
        band = self._band(chosen.quality)
        if not final or band <= TOLERANCE:
            return results, index, reason
        # None within the tolerance, not even one degree beyond the stop: the data's topology with
        # the highest F-score within the wider band, as fitted or repaired to it.
        by_f = sorted(range(len(results)), key=lambda i: -results[i].quality.f_score)
        found = [(_measured(c).f_score, i, c) for i in by_f
                 if (c := self._of_data_topology(results, i, variant, best - band)) is not None]
        if not found:
            return results, index, reason
        _, i, candidate = max(found, key=lambda item: item[0])
        results[i] = candidate
        return results, i, reason

    def _of_data_topology(self, results, i: int, variant, floor: float) -> DegreeResult | None:
        """Degree ``i`` (clean, F-score at least ``floor``) as fitted when it has the data's
        topology, else repaired to it by ``variant`` (``results[i]`` then records the rounds) when
        that is clean and still at least ``floor``; None otherwise."""
        entry = results[i]
        if not self.is_clean(entry.quality) or entry.quality.f_score < floor:
            return None
        if not topology_differs(entry.quality):
            return entry
        results[i], repaired = variant(i)
        if repaired is None or not self.is_clean(repaired.quality) or topology_differs(repaired.quality) or \
                repaired.quality.f_score < floor:
            return None
        return repaired

    def _band(self, quality: Quality) -> float:
        """How far below the best clean F-score the data's topology (known: ``quality``'s) is held."""
        return self.topology_band.get(quality.data_topology.dim, TOLERANCE)  # type: ignore[union-attr]

    def explain(self, results, index, reason, epsilon):
        chosen = results[index]
        if reason == "no_f_gain":
            stop = self._no_gain(results[-1])
        else:
            stop = {"captured": f"the shape was captured (F-score >= {1 - TOLERANCE:g} on a clean degree)",
                    "flattened": f"{PATIENCE} degrees in a row gained nothing substantial",
                    "max_degree": "the last degree was reached",
                    "interrupted": "the run was interrupted"}[reason]
        if not self.is_clean(chosen.quality):
            clean_f = self.best_clean_f(results)
            none = "no degree tried is clean" if not any(self.is_clean(r.quality) for r in results) else \
                f"the clean degrees miss the data (best clean F-score {clean_f:.3f}, below {MISSES_BELOW:g})"
            return (f"degree {chosen.degree}: {none}, so the lowest degree within {TOLERANCE:g} "
                    f"of the best F-score was taken ({chosen.quality.f_score:.3f}: "
                    f"{describe_unclean(chosen.quality) or 'an empty zero set'}); the loop stopped: {stop}")
        right = not topology_differs(chosen.quality)
        lower_wrong = any(self.is_clean(r.quality) and topology_differs(r.quality) and r.degree < chosen.degree
                          and r.quality.f_score >= chosen.quality.f_score - TOLERANCE for r in results)
        # its own fit had another topology, and a repair round gave it the data's (known: an
        # estimate's mismatch is only reported, never repaired)
        known = chosen.quality.data_topology is not None and chosen.quality.data_topology.known
        repaired = " (repaired to the data's topology)" if right and known and self.prefers_topology and any(
            a.get("topology_matches") is False for a in chosen.cleanup) else ""
        best = self.best_clean_f(results)
        if right and known and chosen.quality.f_score < best - TOLERANCE:  # the wider band's choice (settle)
            return (f"degree {chosen.degree}{repaired}: the clean degree with the data's topology of the highest "
                    f"F-score ({chosen.quality.f_score:.3f}), within {self._band(chosen.quality):g} of the best clean "
                    f"F-score ({best:.3f}), "
                    f"none within {TOLERANCE:g} of it having the data's topology; the loop stopped: {stop}")
        which = "clean degree with the data's topology" if lower_wrong and right else "clean degree"
        return (f"degree {chosen.degree}{repaired}: the lowest {which} within {TOLERANCE:g} of the best clean "
                f"F-score ({chosen.quality.f_score:.3f}); the loop stopped: {stop}")

    def _no_gain(self, last) -> str:
        dim = last.polynomial.dim
        return (f"in {dim}D a degree above {self.usual_degrees.get(dim)} is tried only after one that raised the "
                f"best clean F-score by more than {GAIN:g} and left it below {EXTEND_BELOW[dim]:g}, and degree "
                f"{last.degree} did not")

    def reason(self, results, i, index, message, epsilon):
        entry, chosen = results[i], results[index]
        gained = gains(results, i, epsilon)
        tail = f" (gained: {', '.join(gained)})" if gained else (" (no substantial gain)" if i else "")
        if i == index:
            return "selected: " + message + tail
        if not self.is_clean(entry.quality):
            return "rejected: " + (describe_unclean(entry.quality) or "empty zero set") + tail
        f, best = entry.quality.f_score, chosen.quality.f_score
        if f < MISSES_BELOW and not self.is_clean(chosen.quality):
            return f"clean, but misses the data: F-score {f:.3f} is below {MISSES_BELOW:g}" + tail
        if f < best - TOLERANCE:
            return (f"superseded: F-score {f:.3f} is more than {TOLERANCE:g} below degree {chosen.degree}'s "
                    f"{best:.3f}" + tail)
        if topology_differs(entry.quality) and not topology_differs(chosen.quality):
            where = f" within {TOLERANCE:g} of the best," if f <= best + TOLERANCE else \
                f", {f - best:.3f} above degree {chosen.degree}'s,"
            return (f"clean, F-score {f:.3f}{where} but "
                    f"{describe_mismatch(entry.quality.topology, entry.quality.data_topology)}; degree "  # type: ignore[arg-type]
                    f"{chosen.degree} has the data's topology" + tail)
        return f"clean, F-score {f:.3f} within {TOLERANCE:g} of the best, but degree {chosen.degree} is lower" + tail


class TopologyRule(CaptureRule):
    """The capture rule that holds the data's topology at any cost in F-score: a degree whose
    zero set has other loops (2D) or components and genus (3D) than the data, where the data
    tells them with confidence (:func:`topology_differs`), is not clean, and the repair tries to
    fix it first.

    The default capture rule only prefers the data's topology within its tolerance; this one
    gives every development outline one loop, where parts thinner than the tolerance cost F-score
    when they must join the outline (``docs/topology.md``).
    """

    name = "topology"
    checks_topology = True
    prefers_topology = False  # it holds the topology outright


CAPTURE = CaptureRule()
GEOMETRIC = GeometricRule()
PAPER = PaperRule()
TOPOLOGY = TopologyRule()
#: The rules by name: the names the public API and ``ipfit fit --rule`` accept.
RULES: Mapping[str, DegreeRule] = {rule.name: rule for rule in (CAPTURE, GEOMETRIC, PAPER, TOPOLOGY)}


def get_rule(rule: str | DegreeRule) -> DegreeRule:
    """The rule object of ``rule``: a :class:`DegreeRule` as is, a name (any case) from :data:`RULES`.

    >>> get_rule("Capture") is CAPTURE
    True
    """
    if isinstance(rule, DegreeRule):
        return rule
    return RULES[check_choice(rule, "rule", RULES)]
