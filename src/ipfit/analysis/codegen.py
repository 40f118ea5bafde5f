"""Export a fitted polynomial as standalone source code: Python, C, GLSL, LaTeX or SymPy.

Every export is self-contained: the data normalisation is folded in (the code first maps
``x`` to ``u = (x − center) / scale``, exactly as :class:`~ipfit.ImplicitPolynomial` does),
then evaluates the polynomial in nested Horner form, one variable at a time, so a degree-g
polynomial costs about one multiply-add per coefficient and no powers. The gradient is
exported too: its coefficients come from the exact derivative maps of :mod:`ipfit.basis`,
divided by the scale (chain rule).

Monomial order
--------------
The coefficient vector is in the graded order of :func:`ipfit.basis.exponents`:
``1, u, v, w, u², uv, uw, v², vw, w², u³, …`` (by total degree, then descending
lexicographic exponents). The LaTeX export lists the terms in that order.

Precision
---------
Python, C and SymPy exports use double precision literals that round-trip exactly
(``repr``), so they agree with ``poly(points)`` to rounding (about 1e-15 of the sum of the
absolute terms). GLSL is single precision: within 1e-6 × degree of that sum (the tested
tolerance), which far from the data, where the terms grow like ``|u|**degree``, is large
compared with f itself.

>>> from ipfit import ImplicitPolynomial
>>> circle = ImplicitPolynomial.from_coefficients([-1, 0, 0, 1, 0, 1], dim=2)
>>> print(to_source(circle, "python").splitlines()[-1])
    return (u * 2.0) / s, (v * 2.0) / s
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .. import basis
from .._utils.validation import check_choice

__all__ = ["LANGUAGES", "to_source", "horner"]

LANGUAGES = ("python", "c", "glsl", "latex", "sympy")
_INPUTS = ("x", "y", "z")
_NORMALISED = ("u", "v", "w")


def horner(terms: dict[tuple[int, ...], float], variables: tuple[str, ...],
           number: Callable[[float], str] = repr) -> str:
    """Nested Horner expression of ``{exponent tuple: coefficient}`` in ``variables``.

    The polynomial is Horner in the first variable with coefficients that are themselves
    nested in the remaining variables.

    >>> horner({(0, 0): -1.0, (2, 0): 1.0, (0, 2): 1.0}, ("u", "v"))
    '(-1.0 + v * (v * 1.0)) + u * (u * 1.0)'
    """
    terms = {e: c for e, c in terms.items() if c != 0.0}
    if not terms:
        return number(0.0)
    if not variables:
        return number(float(terms[()]))
    var, rest = variables[0], variables[1:]
    groups: dict[int, dict[tuple[int, ...], float]] = {}
    for e, c in terms.items():
        groups.setdefault(e[0], {})[e[1:]] = c
    expr = ""
    for power in range(max(groups), -1, -1):
        inner = horner(groups[power], rest, number) if power in groups else ""
        if not expr:
            expr = inner
        elif inner:
            expr = f"{_wrap(inner)} + {var} * {_wrap(expr)}"
        else:
            expr = f"{var} * {_wrap(expr)}"
    return expr


def _wrap(expr: str) -> str:
    return expr if " " not in expr else f"({expr})"


def _terms(exponents, coefficients) -> dict[tuple[int, ...], float]:
    return {tuple(e): float(c) for e, c in zip(exponents.tolist(), coefficients, strict=True)}


def _gradient_terms(poly) -> list[dict[tuple[int, ...], float]]:
    low = basis.exponents(poly.dim, max(poly.degree - 1, 0))
    return [_terms(low, dmap @ poly.coefficients) for dmap in basis.derivative_maps(poly.dim, poly.degree)]


def _header(poly, comment: str) -> list[str]:
    names = ", ".join(_INPUTS[: poly.dim])
    lines = [
        f"ipfit export: implicit polynomial f({names}), dimension {poly.dim}, degree {poly.degree}, "
        f"{poly.n_coefficients} coefficients" + (f", method {poly.method}" if poly.method else ""),
        f"f({names}) = p(u) with u = (({names}) - center) / scale, p in nested Horner form;",
        "the zero set f = 0 is the fitted shape, f > 0 outside for a canonical fit.",
    ]
    return [f"{comment} {line}" for line in lines]


def _python(poly) -> str:
    dim, c, s = poly.dim, [float(v) for v in poly.center], float(poly.scale)
    args = ", ".join(_INPUTS[:dim])
    setup = [f"    s = {s!r}"] + [f"    {_NORMALISED[j]} = ({_INPUTS[j]} - {c[j]!r}) / s" for j in range(dim)]
    grad = ", ".join(f"({horner(t, _NORMALISED[:dim])}) / s" for t in _gradient_terms(poly))
    lines = _header(poly, "#") + [
        "# Works on floats and on numpy arrays alike.", "",
        f"def f({args}):", *setup, f"    return {horner(_terms(poly.exponents, poly.coefficients), _NORMALISED[:dim])}",
        "", "", f"def gradient({args}):", *setup, f"    return {grad}",
    ]
    return "\n".join(lines) + "\n"


def _sympy(poly) -> str:
    dim, c, s = poly.dim, [float(v) for v in poly.center], float(poly.scale)
    names = _INPUTS[:dim]
    lines = _header(poly, "#") + [
        "import sympy", "",
        f"{', '.join(names)}{',' if dim == 1 else ''} = sympy.symbols({' '.join(names)!r}, real=True)",
        f"s = sympy.Float({s!r})",
        *[f"{_NORMALISED[j]} = ({names[j]} - sympy.Float({c[j]!r})) / s" for j in range(dim)],
        f"f = {horner(_terms(poly.exponents, poly.coefficients), _NORMALISED[:dim])}",
        f"gradient = [sympy.diff(f, var) for var in ({', '.join(names)})]",
    ]
    return "\n".join(lines) + "\n"


def _c_like(poly, scalar: str, number: Callable[[float], str], const: str) -> tuple[list[str], list[str], str]:
    dim = poly.dim
    params = ", ".join(f"{scalar} {n}" for n in _INPUTS[:dim])
    setup = [f"    {const}{scalar} s = {number(float(poly.scale))};"] + [
        f"    {const}{scalar} {_NORMALISED[j]} = ({_INPUTS[j]} - {number(float(poly.center[j]))}) / s;"
        for j in range(dim)]
    grads = [horner(t, _NORMALISED[:dim], number) for t in _gradient_terms(poly)]
    return setup, grads, params


def _c_number(value: float) -> str:
    return f"({value!r})" if value < 0 else repr(value)


def _c(poly) -> str:
    dim = poly.dim
    setup, grads, params = _c_like(poly, "double", _c_number, "const ")
    body = horner(_terms(poly.exponents, poly.coefficients), _NORMALISED[:dim], _c_number)
    lines = _header(poly, "//") + [
        f"// Compile with any C99 compiler; gradient writes {dim} values to out.", "",
        f"double ipfit_f({params})", "{", *setup, f"    return {body};", "}", "",
        f"void ipfit_gradient({params}, double out[{dim}])", "{", *setup,
        *[f"    out[{j}] = ({g}) / s;" for j, g in enumerate(grads)], "}",
    ]
    return "\n".join(lines) + "\n"


def _glsl_number(value: float) -> str:
    # Single precision: 9 significant digits round-trip a float; the literal needs a '.' or 'e'.
    text = f"{float(np.float32(value)):.9g}"
    if "." not in text and "e" not in text:
        text += ".0"
    return f"({text})" if value < 0 else text


def _glsl(poly) -> str:
    dim = poly.dim
    vec = f"vec{dim}"
    setup, grads, params = _c_like(poly, "float", _glsl_number, "")  # GLSL 3.30: const needs constant initialisers
    body = horner(_terms(poly.exponents, poly.coefficients), _NORMALISED[:dim], _glsl_number)
    comps = ", ".join(f"p.{a}" for a in "xyz"[:dim])
    lines = _header(poly, "//") + [
        "// Single precision (see ipfit.analysis.codegen). ipfit_sdf is f / |grad f|, the first-order distance",
        "// to the zero set: exact on the surface, an estimate away from it, so ray-march it with",
        "// steps of a fraction of its value (e.g. 0.5 * ipfit_sdf) and stop when it is ~ 1e-4.", "",
        f"float ipfit_f({params})", "{", *setup, f"    return {body};", "}", "",
        f"{vec} ipfit_gradient({params})", "{", *setup,
        f"    return {vec}({', '.join(f'({g}) / s' for g in grads)});", "}", "",
        f"float ipfit_f({vec} p) {{ return ipfit_f({comps}); }}",
        f"{vec} ipfit_gradient({vec} p) {{ return ipfit_gradient({comps}); }}",
        f"float ipfit_sdf({vec} p) {{ return ipfit_f(p) / max(length(ipfit_gradient(p)), 1e-20); }}",
    ]
    return "\n".join(lines) + "\n"


def _latex_number(value: float) -> str:
    mantissa, _, exp = f"{abs(value):.17g}".partition("e")
    text = mantissa if not exp else rf"{mantissa} \times 10^{{{int(exp)}}}"
    return text


def _latex_monomial(e) -> str:
    parts = []
    for var, k in zip(_NORMALISED, e, strict=False):  # u, v, w: only the first dim are used
        if k == 1:
            parts.append(var)
        elif k > 1:
            parts.append(f"{var}^{{{k}}}")
    return r"\,".join(parts)


def _latex(poly) -> str:
    dim = poly.dim
    names = ", ".join(_INPUTS[:dim])
    terms = []
    for e, c in zip(poly.exponents.tolist(), poly.coefficients, strict=True):
        if c == 0:
            continue
        mono = _latex_monomial(e)
        sign = "-" if c < 0 else "+"
        body = _latex_number(float(c)) + (r"\," + mono if mono else "")
        terms.append(f"{sign} {body}")
    if not terms:
        terms = ["+ 0"]
    first = terms[0][2:] if terms[0].startswith("+") else terms[0]
    rows = [first] + terms[1:]
    # Four terms per line keeps a degree-8 surface printable.
    lines = [" ".join(rows[i:i + 4]) for i in range(0, len(rows), 4)]
    c, s = [float(v) for v in poly.center], float(poly.scale)
    defs = ", \\quad ".join(f"{_NORMALISED[j]} = \\frac{{{_INPUTS[j]} - ({c[j]!r})}}{{{s!r}}}" for j in range(dim))
    header = [line.replace("nested Horner form", "graded monomial order") for line in _header(poly, "%")]
    out = header + [
        r"\begin{aligned}",
        f"f({names}) ={{}}& " + " \\\\\n&".join(lines) + r", \\",
        f"&\\text{{where }} {defs}.",
        r"\end{aligned}",
    ]
    return "\n".join(out) + "\n"


_WRITERS = {"python": _python, "c": _c, "glsl": _glsl, "latex": _latex, "sympy": _sympy}


def to_source(poly, language: str) -> str:
    """Source code of ``poly`` (and of its gradient) in ``language``.

    Parameters
    ----------
    poly : ImplicitPolynomial
    language : one of ``"python"``, ``"c"``, ``"glsl"``, ``"latex"``, ``"sympy"``.

    Returns
    -------
    str
        Python: functions ``f(x, y[, z])`` and ``gradient(...)`` (numpy-friendly).
        C: ``double ipfit_f(double x, ...)`` and ``void ipfit_gradient(..., double out[])``.
        GLSL: ``float ipfit_f(vecN p)``, ``vecN ipfit_gradient(vecN p)`` and
        ``float ipfit_sdf(vecN p)`` for ray marching. LaTeX: an ``aligned`` block.
        SymPy: a script defining the expression ``f`` and the list ``gradient``.

    Examples
    --------
    >>> from ipfit import ImplicitPolynomial, Normalization
    >>> p = ImplicitPolynomial.from_coefficients([-1, 0, 0, 1, 0, 1], dim=2,
    ...                                          normalization=Normalization([1.0, 0.0], 2.0))
    >>> namespace = {}
    >>> exec(to_source(p, "python"), namespace)
    >>> namespace["f"](3.0, 0.0), float(p([[3.0, 0.0]])[0])
    (0.0, 0.0)
    """
    language = check_choice(language, "language", LANGUAGES)
    return _WRITERS[language](poly)
