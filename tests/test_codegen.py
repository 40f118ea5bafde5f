"""Exported source, run by an interpreter or compiler, equals poly(points) and its gradient."""

from __future__ import annotations

import re
import shutil
import subprocess

import numpy as np
import pytest

import ipfit
from ipfit import ImplicitPolynomial, Normalization
from ipfit.analysis.codegen import LANGUAGES, to_source
from ipfit.exceptions import InvalidInputError


def _random_poly(rng, dim, degree):
    n = ipfit.basis.n_coefficients(dim, degree)
    norm = Normalization(rng.uniform(-3, 3, dim), float(rng.uniform(0.5, 4)))
    return ImplicitPolynomial.from_coefficients(rng.standard_normal(n), dim, normalization=norm)


def _term_scale(poly, points):
    """Σ|a_k m_k(u)|: the size of the sum being evaluated, the natural rounding reference."""
    u = poly.normalization.apply(points)
    return np.abs(ipfit.basis.monomials(u, poly.exponents)) @ np.abs(poly.coefficients)


def _points(rng, poly, n=200):
    return poly.center + poly.scale * rng.uniform(-1.5, 1.5, (n, poly.dim))


@pytest.fixture(params=[(2, 3), (2, 6), (3, 4), (3, 7)], ids=lambda p: f"{p[0]}d-deg{p[1]}")
def poly(request, rng):
    return _random_poly(rng, *request.param)


def test_python_export_matches_evaluation(poly, rng):
    pts = _points(rng, poly)
    namespace: dict = {}
    exec(to_source(poly, "python"), namespace)
    values = namespace["f"](*pts.T)
    grads = np.column_stack(namespace["gradient"](*pts.T))
    scale = _term_scale(poly, pts)
    assert np.all(np.abs(values - poly(pts)) <= 1e-12 * scale)
    grad_scale = np.linalg.norm(poly.gradient(pts), axis=1) + scale / poly.scale
    assert np.all(np.linalg.norm(grads - poly.gradient(pts), axis=1) <= 1e-12 * grad_scale)


def test_method_and_module_agree(poly):
    assert poly.to_source("c") == to_source(poly, "c")


def _compile_and_run(tmp_path, source: str, main: str, flags=()) -> np.ndarray:
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler (cc) on PATH")
    (tmp_path / "f.c").write_text(source + "\n#include <stdio.h>\n" + main)
    exe = tmp_path / "f"
    subprocess.run([cc, "-std=c99", "-O2", "-Wall", "-Werror", *flags, "-o", str(exe), str(tmp_path / "f.c"), "-lm"],
                   check=True, capture_output=True, text=True)
    out = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout
    return np.array([[float(v) for v in line.split()] for line in out.splitlines()])


def _c_main(pts, call_f: str, call_g: str | None, dim: int, scalar: str = "double") -> str:
    rows = ",\n".join("{" + ", ".join(repr(float(v)) for v in p) + "}" for p in pts)
    args = ", ".join(f"p[i][{j}]" for j in range(dim))
    grad = f"{scalar} g[{dim}]; {call_g}({args}, g);" if call_g else ""
    grad_print = "".join(f' printf(" %.17g", (double)g[{j}]);' for j in range(dim)) if call_g else ""
    return (f"static const double p[{len(pts)}][{dim}] = {{\n{rows}}};\n"
            "int main(void) {\n"
            f"  for (int i = 0; i < {len(pts)}; ++i) {{ {grad}\n"
            f'    printf("%.17g", (double){call_f}({args}));{grad_print} printf("\\n"); }}\n'
            "  return 0;\n}\n")


def test_c_export_compiles_and_matches(poly, rng, tmp_path):
    pts = _points(rng, poly)
    out = _compile_and_run(tmp_path, to_source(poly, "c"), _c_main(pts, "ipfit_f", "ipfit_gradient", poly.dim),
                           )
    scale = _term_scale(poly, pts)
    assert np.all(np.abs(out[:, 0] - poly(pts)) <= 1e-12 * scale)
    grad_scale = np.linalg.norm(poly.gradient(pts), axis=1) + scale / poly.scale
    assert np.all(np.linalg.norm(out[:, 1:] - poly.gradient(pts), axis=1) <= 1e-12 * grad_scale)


def _glsl_scalar_function(source: str) -> str:
    """The scalar ``float ipfit_f(float ...)`` body of the GLSL export: valid C as well."""
    match = re.search(r"float ipfit_f\(float[^)]*\)\n\{.*?\n\}\n", source, re.S)
    assert match, source
    return match.group(0)


def test_glsl_single_precision_tolerance(poly, rng, tmp_path):
    # GLSL's float arithmetic, reproduced by C with float variables and float literals.
    pts = _points(rng, poly)
    body = _glsl_scalar_function(to_source(poly, "glsl"))
    out = _compile_and_run(tmp_path, body, _c_main(pts, "ipfit_f", None, poly.dim, "float"),
                           flags=("-fsingle-precision-constant", "-Wno-double-promotion"))
    scale = _term_scale(poly, pts)
    # Stated tolerance (ipfit.analysis.codegen): a few 1e-6 of the term sum, times the degree.
    assert np.all(np.abs(out[:, 0] - poly(pts)) <= 1e-6 * poly.degree * scale)


def test_glsl_compiles_with_glslang(poly, tmp_path):
    validator = shutil.which("glslangValidator")
    if validator is None:
        pytest.skip("glslangValidator not installed (Debian/Ubuntu package glslang-tools)")
    vec = f"vec{poly.dim}"
    shader = ("#version 330 core\n" + to_source(poly, "glsl") + "out vec4 color;\n"
              f"void main() {{ {vec} p = {vec}(gl_FragCoord.{'xyz'[:poly.dim]}); "
              f"color = vec4(ipfit_sdf(p), ipfit_gradient(p).x, ipfit_f(p), 1.0); }}\n")
    path = tmp_path / "shader.frag"
    path.write_text(shader)
    result = subprocess.run([validator, str(path)], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr


def test_sympy_export_matches(poly, rng):
    sympy = pytest.importorskip("sympy", reason="sympy not installed (pip install 'ipfit[sympy]')")
    pts = _points(rng, poly, 50)
    namespace: dict = {}
    exec(to_source(poly, "sympy"), namespace)
    symbols = sympy.symbols("x y z"[: 2 * poly.dim - 1], real=True)
    f = sympy.lambdify(symbols, namespace["f"], "numpy")
    g = sympy.lambdify(symbols, namespace["gradient"], "numpy")
    scale = _term_scale(poly, pts)
    assert np.all(np.abs(f(*pts.T) - poly(pts)) <= 1e-12 * scale)
    grads = np.column_stack(g(*pts.T))
    grad_scale = np.linalg.norm(poly.gradient(pts), axis=1) + scale / poly.scale
    assert np.all(np.linalg.norm(grads - poly.gradient(pts), axis=1) <= 1e-12 * grad_scale)


def _parse_latex(text: str, dim: int):
    """Coefficients back from the LaTeX block: sign, mantissa × 10^exp, monomial."""
    body = text.split(r"\begin{aligned}")[1].split(r"\text{where")[0]
    body = body.split("={}&", 1)[1].replace("\\\\", " ").replace("&", " ").rstrip(" ,")
    terms = {}
    pattern = re.compile(r"([+-])?\s*([0-9.]+)(?: \\times 10\^\{(-?\d+)\})?((?:\\,[uvw](?:\^\{\d+\})?)*)")
    for sign, mant, exp, mono in pattern.findall(body):
        value = float(mant) * 10.0 ** int(exp or 0) * (-1 if sign == "-" else 1)
        powers = [0] * dim
        for var, power in re.findall(r"([uvw])(?:\^\{(\d+)\})?", mono):
            powers["uvw".index(var)] = int(power or 1)
        terms[tuple(powers)] = value
    return terms


def test_latex_lists_every_coefficient_in_graded_order(poly):
    text = to_source(poly, "latex")
    terms = _parse_latex(text, poly.dim)
    assert list(terms) == [tuple(e) for e in poly.exponents.tolist()]
    np.testing.assert_allclose([terms[tuple(e)] for e in poly.exponents.tolist()], poly.coefficients, rtol=1e-15)
    assert f"{float(poly.scale)!r}" in text and f"{float(poly.center[0])!r}" in text


def test_unknown_language_is_a_clear_error(poly):
    with pytest.raises(InvalidInputError, match="language: expected one of 'python'"):
        to_source(poly, "fortran")
    assert set(LANGUAGES) == {"python", "c", "glsl", "latex", "sympy"}
