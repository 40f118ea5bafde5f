"""Figures: single panels, paper-style result figures, and the figures script (non-blank PNGs)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from ipfit import ReadError, basis
from ipfit.datasets import synthetic

REPO = Path(__file__).resolve().parents[1]


def padded(poly, degree: int) -> list[float]:
    """Coefficients of ``poly`` in the basis of a higher ``degree`` (graded order is nested)."""
    coef = np.zeros(basis.n_coefficients(poly.dim, degree))
    coef[: poly.n_coefficients] = poly.coefficients
    return coef.tolist()


def adaptive_result(final, others, selected: int, comparisons: bool = True) -> dict:
    """An adaptive-format result dict built from exact polynomials (identity normalisation).

    ``others`` maps degree → polynomial for the per-degree table; ``final`` is the selected fit.
    """
    data = final.to_dict()
    data["selected_degree"] = selected
    data["degrees"] = [{"degree": g, "dissimilarity": 0.01 * g, "smoothness": 0.8 + 0.02 * g, "distance": 0.1,
                        "seconds": 0.0, "coefficients": padded(p, g), "method": "3l"}
                       for g, p in sorted(others.items())]
    if comparisons:
        data["comparisons"] = {"lstsq": {"degree": selected, "coefficients": padded(others[min(others)], selected)},
                               "3l": {"degree": selected, "coefficients": padded(final, selected)}}
    return data


def close(ax) -> None:
    import matplotlib.pyplot as plt

    plt.close(ax.figure)


def nonblank(path: Path) -> float:
    from PIL import Image

    pixels = np.asarray(Image.open(path).convert("L"), dtype=float)
    return float(pixels.var())


@pytest.fixture(scope="module")
def ellipse_result():
    shape = synthetic.ellipse()
    circle = synthetic.circle(radius=1.5).polynomial
    return shape, adaptive_result(shape.polynomial, {2: shape.polynomial, 4: circle}, selected=2)


@pytest.fixture(scope="module")
def torus_result():
    shape = synthetic.torus(800)
    sphere = synthetic.ellipsoid(axes=(1.4, 1.4, 0.5)).polynomial
    return shape, adaptive_result(shape.polynomial, {2: sphere, 4: shape.polynomial}, selected=4)


def test_plot_curve_draws_zero_set_and_points():
    from ipfit.plotting import plot_curve

    shape = synthetic.circle()
    ax = plot_curve(shape.polynomial, shape.points)
    assert len(ax.lines) == 1 and len(ax.collections) == 1
    x = ax.lines[0].get_xdata()
    assert np.abs(x).max() == pytest.approx(1.0, abs=0.02)
    close(ax)


def test_plot_surface_shaded_and_decimated():
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    from ipfit.plotting import plot_surface
    from ipfit.zeroset import extract_zero_set

    shape = synthetic.torus(400)
    zs = extract_zero_set(shape.polynomial, points=shape.points, resolution=64)
    ax = plot_surface(None, shape.points, zero_set=zs, max_faces=2000, show_points=True)
    polys = [c for c in ax.collections if isinstance(c, Poly3DCollection)]
    assert len(polys) == 1
    assert len(polys[0].get_paths()) <= 2000
    colors = polys[0].get_facecolor()
    assert np.ptp(colors[:, 0]) > 0.1  # shaded, not one flat colour
    close(ax)


def test_plot_smoothness_marks_selected():
    from ipfit import InvalidInputError
    from ipfit.plotting import plot_smoothness

    ax = plot_smoothness([2, 4, 6], [0.8, 0.9, 0.91], selected=4)
    assert len(ax.lines) == 2
    assert list(ax.get_xticks()) == [2, 4, 6]
    with pytest.raises(InvalidInputError, match="smoothness"):
        plot_smoothness([2, 4], [0.8], ax=ax)
    close(ax)


def test_plot_result_panels_2d(ellipse_result, tmp_path):
    from ipfit.plotting import plot_result

    shape, result = ellipse_result
    fig = plot_result(result, shape.points, tmp_path / "e.png")
    titles = [ax.get_title() for ax in fig.axes]
    # 2 degrees + smoothness + classic + 3L
    assert len(titles) == 5
    assert titles[0].startswith("(a) degree 2 (selected)")
    assert "smoothness" in titles[2] and "classic linear" in titles[3] and "3L" in titles[4]
    assert nonblank(tmp_path / "e.png") > 0
    assert [p.name for p in tmp_path.iterdir()] == ["e.png"]


def test_plot_result_panels_3d(torus_result, tmp_path):
    from ipfit.plotting import plot_result

    shape, result = torus_result
    fig = plot_result(result, shape.points, tmp_path / "t.png", resolution=32, title="torus")
    titles = [ax.get_title() for ax in fig.axes]
    # point cloud + 2 degrees + smoothness + classic + 3L
    assert len(titles) == 6 and "point cloud" in titles[0] and "(selected)" in titles[2]
    assert nonblank(tmp_path / "t.png") > 0


def test_plot_result_plain_polynomial_and_path(tmp_path):
    from ipfit.plotting import plot_result

    poly = synthetic.sphere().polynomial
    poly.save(tmp_path / "s.json")
    fig = plot_result(tmp_path / "s.json", resolution=24)
    assert len(fig.axes) == 1
    fig = plot_result(poly, resolution=24, path=tmp_path / "s.png")
    assert nonblank(tmp_path / "s.png") > 0


def test_result_view_entries_with_their_own_normalization():
    from ipfit import ImplicitPolynomial, Normalization
    from ipfit.plotting import result_view

    shape = synthetic.circle()
    result = adaptive_result(shape.polynomial, {2: shape.polynomial}, selected=2)
    own = Normalization([0.5, 0.0], 2.0)
    result["comparisons"]["3l"]["normalization"] = own.to_dict()
    view = result_view(result)
    assert view.selected == 2 and [d.degree for d in view.degrees] == [2]
    assert view.comparisons["3l"].normalization.scale == 2.0
    assert isinstance(view.comparisons["lstsq"], ImplicitPolynomial)


@pytest.mark.parametrize("mutate, match", [
    (lambda d: d.update(degrees=[{"coefficients": [1.0]}]), "degree"),
    (lambda d: d.update(degrees=[{"degree": 4, "coefficients": [1.0, 2.0]}]), "degree 4"),
    (lambda d: d.update(format="other"), "not an ipfit result"),
])
def test_result_view_errors(mutate, match):
    from ipfit.plotting import result_view

    data = synthetic.circle().polynomial.to_dict()
    mutate(data)
    with pytest.raises(ReadError, match=match):
        result_view(data)


def test_load_result_errors(tmp_path):
    from ipfit.plotting import load_result

    with pytest.raises(ReadError, match="no such file"):
        load_result(tmp_path / "missing.json")
    (tmp_path / "bad.json").write_text("{oops")
    with pytest.raises(ReadError, match="not valid JSON"):
        load_result(tmp_path / "bad.json")


def _figures_module():
    spec = importlib.util.spec_from_file_location("ipfit_figures_script", REPO / "experiments" / "figures.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_figures_script_writes_nonblank_figures(ellipse_result, torus_result, tmp_path):
    figures = _figures_module()
    results = tmp_path / "results"
    results.mkdir()
    for name, (_, result) in {"ellipse": ellipse_result, "torus": torus_result}.items():
        (results / f"{name}.json").write_text(json.dumps(result))
    out = tmp_path / "figures"
    assert figures.main(["--results", str(results), "-o", str(out), "--resolution", "32"]) == 0
    for name in ("ellipse", "torus"):
        png = out / f"{name}.png"
        assert png.exists() and nonblank(png) > 0


@pytest.mark.slow
def test_figures_for_every_bundled_dataset(tmp_path):
    bundled = pytest.importorskip("ipfit.datasets.bundled")
    pytest.importorskip("ipfit.io")
    figures = _figures_module()
    out = tmp_path / "figures"
    assert figures.main(["--results", str(tmp_path / "results"), "--fit-missing", "-o", str(out)]) == 0
    for name in bundled.dataset_names():
        png = out / f"{name}.png"
        assert png.exists() and nonblank(png) > 0, name
