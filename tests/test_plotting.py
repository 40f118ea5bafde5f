"""Figures: single panels, paper-style result figures, and the figures script (non-blank PNGs)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from ipfit import InvalidInputError, basis
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
    from ipfit.viz.plotting import plot_curve

    shape = synthetic.circle()
    ax = plot_curve(shape.polynomial, shape.points)
    assert len(ax.lines) == 1 and len(ax.collections) == 1
    x = ax.lines[0].get_xdata()
    assert np.abs(x).max() == pytest.approx(1.0, abs=0.02)
    close(ax)


def test_plot_surface_shaded_and_decimated():
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    from ipfit.viz.plotting import plot_surface
    from ipfit.zeroset.extract import extract_zero_set

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
    from ipfit.viz.plotting import plot_smoothness

    ax = plot_smoothness([2, 4, 6], [0.8, 0.9, 0.91], selected=4)
    assert len(ax.lines) == 2
    assert list(ax.get_xticks()) == [2, 4, 6]
    with pytest.raises(InvalidInputError, match="smoothness"):
        plot_smoothness([2, 4], [0.8], ax=ax)
    close(ax)


def test_plot_result_panels_2d(ellipse_result, tmp_path):
    from ipfit.viz.plotting import plot_result

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
    from mpl_toolkits.mplot3d.art3d import Path3DCollection, Poly3DCollection

    from ipfit.viz.plotting import plot_result

    shape, result = torus_result
    fig = plot_result(result, shape.points, tmp_path / "t.png", resolution=32, title="torus")
    titles = [ax.get_title() for ax in fig.axes]
    # 2 degrees + smoothness + classic + 3L; the points are drawn on every surface, not apart
    assert len(titles) == 5 and "(selected)" in titles[1] and not any("point cloud" in t for t in titles)
    for ax in (fig.axes[0], fig.axes[1], fig.axes[3], fig.axes[4]):
        (scatter,) = [c for c in ax.collections if isinstance(c, Path3DCollection)]
        (surface,) = [c for c in ax.collections if isinstance(c, Poly3DCollection)]
        # every point, see-through, beneath the surface (tests/test_figures_3d.py checks the picture)
        assert len(scatter._offsets3d[0]) == len(shape.points)
        assert scatter.get_zorder() < surface.get_zorder() and scatter.get_alpha() < 1
    assert nonblank(tmp_path / "t.png") > 0


def test_plot_result_plain_polynomial_and_path(tmp_path):
    from ipfit.viz.plotting import plot_result

    poly = synthetic.sphere().polynomial
    poly.save(tmp_path / "s.json")
    fig = plot_result(tmp_path / "s.json", resolution=24)
    assert len(fig.axes) == 1 and fig.axes[0].get_title().startswith("degree 2")
    fig = plot_result(poly, resolution=24, path=tmp_path / "s.png")
    assert nonblank(tmp_path / "s.png") > 0


def test_fixed_degree_result_is_one_panel_for_that_degree(ellipse_result):
    from ipfit.viz.plotting import plot_result

    shape, result = ellipse_result
    fixed = dict(result, degrees=result["degrees"][:1], comparisons={})
    fig = plot_result(fixed, shape.points)
    (ax,) = fig.axes
    title = ax.get_title()
    assert title.startswith("degree 2 (fixed), 3L") and "smoothness 0.840" in title  # the entry's own measures
    assert ax.name != "3d" and len(ax.lines) == 1  # the curve, no smoothness-vs-degree panel


def test_smoothness_axis_plain_labels_and_no_fake_dip():
    from ipfit.viz.plotting import MIN_SMOOTHNESS_SPAN, plot_smoothness

    # a straight line's smoothness differs in the 6th decimal between degrees
    ax = plot_smoothness([2, 4, 6], [0.8960001, 0.8960031, 0.8960012], selected=2)
    ax.figure.canvas.draw()
    lo, hi = ax.get_ylim()
    assert hi - lo >= MIN_SMOOTHNESS_SPAN and lo < 0.8960001 and hi > 0.8960031
    assert ax.yaxis.get_offset_text().get_text() == ""
    labels = [float(t.get_text().replace("\u2212", "-")) for t in ax.get_yticklabels()]
    assert len(labels) >= 3
    np.testing.assert_allclose(labels, ax.get_yticks(), atol=1e-9)  # each label is its tick's value
    close(ax)
    ax = plot_smoothness([2, 4], [0.5, 0.9])  # a real gain keeps its own range
    assert ax.get_ylim()[1] - ax.get_ylim()[0] == pytest.approx(0.44)
    close(ax)


def test_points_drawn_over_a_surface_face_the_camera():
    """Against matplotlib's own camera: the points shown are those on the sphere's near half."""
    from mpl_toolkits.mplot3d.art3d import Path3DCollection

    from ipfit.viz.plotting import plot_surface

    shape = synthetic.sphere(800)
    for view, up in [((20.0, -60.0), "z"), ((0.0, 0.0), "z"), ((-35.0, 120.0), "y"), ((60.0, 200.0), "x")]:
        ax = plot_surface(shape.polynomial, shape.points, resolution=20, show_points=True, view=view, up=up)
        ax.figure.canvas.draw()
        camera = ax._get_camera_loc()  # the eye's position in data coordinates, as matplotlib places it
        (scatter,) = [c for c in ax.collections if isinstance(c, Path3DCollection)]
        shown = {tuple(q) for q in np.column_stack(scatter._offsets3d).tolist()}
        near = {tuple(p) for p in shape.points.tolist() if np.dot(p, camera) > 0}  # the normal of a unit sphere is p
        assert shown == near and 0.4 < len(shown) / len(shape.points) < 0.6
        close(ax)


def test_display_points_sample_a_mesh_where_it_has_no_vertices():
    import trimesh

    from ipfit.viz.plotting import display_points

    capsule = trimesh.creation.capsule(height=2.0, radius=0.5)
    vertices, faces = np.asarray(capsule.vertices), np.asarray(capsule.faces)
    assert np.abs(vertices[:, 2]).min() > 0.9  # no vertex along the cylinder
    shown = display_points(vertices, faces, count=2000)
    assert shown.shape == (2000, 3)
    middle = np.abs(shown[:, 2]) < 0.5
    assert middle.sum() > 200  # the cylinder is covered, in proportion to its area
    np.testing.assert_allclose(np.linalg.norm(shown[middle, :2], axis=1), 0.5, atol=0.02)
    np.testing.assert_array_equal(display_points(vertices), vertices)  # no faces: the points themselves


def _two_ovals():
    """(x² − 1)² + y² = 1/4: two ovals around x = ±1."""
    return synthetic.from_terms(2, 4, {(4, 0): 1, (2, 0): -2, (0, 2): 1, (0, 0): 0.75})


def test_spurious_curves_in_their_own_colour():
    from matplotlib.colors import to_rgba

    from ipfit.viz.plotting import SPURIOUS_COLOR, plot_result
    from ipfit.zeroset.extract import extract_zero_set

    poly = _two_ovals()
    zs = extract_zero_set(poly, bounds=[[-2, 2], [-1, 1]])
    right = np.concatenate([c for c in zs.curves if c[:, 0].mean() > 0])
    fig = plot_result(poly, right[::3], margin=2.0)  # the box holds both ovals
    (ax,) = fig.axes
    colours = {("right" if line.get_xdata().mean() > 0 else "left"): to_rgba(line.get_color()) for line in ax.lines}
    assert colours["left"] == to_rgba(SPURIOUS_COLOR) and colours["right"] != to_rgba(SPURIOUS_COLOR)
    assert "1 spurious piece (red)" in ax.get_title()
    fig = plot_result(poly, right[::3], margin=2.0, mark_spurious=False)
    assert len(fig.axes[0].lines) == 2
    assert to_rgba(SPURIOUS_COLOR) not in {to_rgba(line.get_color()) for line in fig.axes[0].lines}


def test_spurious_surface_pieces_are_red_and_see_through():
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    from ipfit.viz.plotting import SPURIOUS_ALPHA, plot_surface
    from ipfit.zeroset.quality import spurious_components
    from ipfit.zeroset.extract import extract_zero_set

    blobs = synthetic.from_terms(3, 4, {(4, 0, 0): 1, (2, 0, 0): -2, (0, 2, 0): 1, (0, 0, 2): 1, (0, 0, 0): 0.75})
    zs = extract_zero_set(blobs, bounds=[[-2, 2], [-1, 1], [-1, 1]], resolution=40)
    right = zs.vertices[zs.vertices[:, 0] > 0]
    flags = spurious_components(zs, right)
    assert flags.tolist().count(True) == 1
    ax = plot_surface(None, zero_set=zs, spurious=flags)
    shape, ghost = [c for c in ax.collections if isinstance(c, Poly3DCollection)]
    left = flags[zs.component_labels]
    assert len(ghost.get_facecolor()) == left.sum() and len(shape.get_facecolor()) == (~left).sum()
    assert ghost.get_zorder() > shape.get_zorder()  # drawn on top: visible even inside the shape
    ghost_rgba, shape_rgba = ghost.get_facecolor(), shape.get_facecolor()
    assert np.all(ghost_rgba[:, 3] == SPURIOUS_ALPHA) and np.all(shape_rgba[:, 3] == 1.0)
    assert np.all(ghost_rgba[:, 0] > ghost_rgba[:, 2]) and np.all(shape_rgba[:, 2] > shape_rgba[:, 0])  # red, blue
    with pytest.raises(InvalidInputError, match="spurious: expected 2 flags"):
        plot_surface(None, zero_set=zs, spurious=[True], ax=ax)
    close(ax)


@pytest.mark.parametrize("name", ["fig.xyz", "fig", "fig.png.partial.raw"])
def test_save_figure_refuses_unknown_suffixes(tmp_path, name):
    from ipfit.viz.plotting import plot_smoothness, save_figure

    ax = plot_smoothness([2, 4], [0.8, 0.9])
    with pytest.raises(InvalidInputError, match=r"^path: expected a figure file name ending in \.png, \.pdf"):
        save_figure(ax.figure, tmp_path / name)
    assert list(tmp_path.iterdir()) == []
    close(ax)


def test_save_figure_bounds_the_pixel_count(tmp_path):
    from ipfit.viz.plotting import MAX_PIXELS, plot_smoothness, save_figure

    ax = plot_smoothness([2, 4], [0.8, 0.9])
    width, height = ax.figure.get_size_inches()
    limit = int(np.sqrt(MAX_PIXELS / (width * height)))
    with pytest.raises(InvalidInputError, match=rf"^dpi: expected at most {limit} .* got 100000"):
        save_figure(ax.figure, tmp_path / "s.png", dpi=100000)
    with pytest.raises(InvalidInputError, match="dpi"):
        save_figure(ax.figure, tmp_path / "s.png", dpi=0)
    save_figure(ax.figure, tmp_path / "s.svg", dpi=limit)  # at the limit: fine
    assert [p.name for p in tmp_path.iterdir()] == ["s.svg"]
    close(ax)


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


def test_result_without_per_degree_coefficients_shows_the_final_fit(ellipse_result):
    from ipfit.viz.plotting import plot_result

    shape, result = ellipse_result
    bare = dict(result, degrees=[{k: v for k, v in d.items() if k != "coefficients"} for d in result["degrees"]],
                comparisons={})
    fig = plot_result(bare, shape.points)
    titles = [ax.get_title() for ax in fig.axes]
    assert len(titles) == 2 and titles[0].startswith("(a) degree 2 (selected)") and "smoothness" in titles[1]


def test_interrupted_run_is_not_called_fixed(ellipse_result):
    from ipfit.viz.plotting import plot_result

    shape, result = ellipse_result
    stopped = dict(result, degrees=result["degrees"][:1], comparisons={}, adaptive={"reason": "interrupted"})
    assert plot_result(stopped, shape.points).axes[0].get_title().startswith("degree 2 (interrupted)")


# -- outliers in their own colour -------------------------------------------------------------

def planted(shape, result: dict, n_outliers: int = 20, seed: int = 0, n_points: bool = True):
    """The shape's points with ``n_outliers`` uniform ones in its box grown by 20% a side, shuffled,
    and ``result`` with an "outliers" section naming exactly those (and ``input.n_points``).

    Returns ``(points, indices, result)``.
    """
    rng = np.random.default_rng(seed)
    lo, hi = shape.points.min(axis=0), shape.points.max(axis=0)
    stray = rng.uniform(lo - 0.2 * (hi - lo), hi + 0.2 * (hi - lo), (n_outliers, shape.points.shape[1]))
    order = rng.permutation(len(shape.points) + n_outliers)
    points = np.vstack([shape.points, stray])[order]
    indices = np.flatnonzero(order >= len(shape.points))
    data = json.loads(json.dumps(result))  # a copy, as read back from a file
    data["outliers"] = {"mode": "auto", "count": n_outliers, "share": n_outliers / len(points), "noise_scale": 0.0,
                        "indices": indices.tolist()}
    if n_points:
        data["input"] = {"source": "planted", "n_points": len(points)}
    return points, indices, data


def rows(points) -> set:
    return {tuple(p) for p in np.asarray(points, dtype=float).tolist()}


def scatters_by_colour(ax) -> dict:
    """rgb → the rows drawn in that colour, over the axes' scatter collections (2D or 3D)."""
    from mpl_toolkits.mplot3d.art3d import Path3DCollection

    found: dict = {}
    for c in ax.collections:
        if isinstance(c, Path3DCollection):
            xyz = np.column_stack(c._offsets3d)
        elif type(c).__name__ == "PathCollection":
            xyz = c.get_offsets()
        else:
            continue
        (rgb,) = {tuple(np.round(f[:3], 6)) for f in c.get_facecolor()}  # one colour per collection
        found.setdefault(rgb, set()).update(rows(xyz))
    return {rgb: found[rgb] for rgb in found if found[rgb]}


def rgb(color) -> tuple:
    from matplotlib.colors import to_rgb

    return tuple(np.round(to_rgb(color), 6))


@pytest.fixture(scope="module")
def fitted_ellipse():
    """A real result: fit_adaptive's to_dict on an ellipse (3L, degrees 2 and 4)."""
    from ipfit import fit_adaptive

    shape = synthetic.ellipse(120)
    return shape, fit_adaptive(shape.points, shape.normals, method="3l", max_degree=4, rule="geometric").to_dict()


@pytest.fixture(scope="module")
def fitted_sphere():
    from ipfit import fit_adaptive

    shape = synthetic.sphere(300)
    return shape, fit_adaptive(shape.points, shape.normals, method="3l", max_degree=2).to_dict()


def test_outlier_colour_stays_apart_for_colour_blind_readers():
    """Against Machado et al. (2009)'s dichromacy simulations (severity 1, linear RGB) and CIEDE2000
    (scikit-image): the outliers stay apart from every other colour of the figure and the viewer."""
    from matplotlib.colors import to_rgb
    from skimage.color import deltaE_ciede2000, rgb2lab

    from ipfit.viz import plotting
    from ipfit.viz.viewer import figure

    machado = {"protanopia": [[0.152286, 1.052583, -0.204868], [0.114503, 0.786281, 0.099216],
                              [-0.003882, -0.048116, 1.051998]],
               "deuteranopia": [[0.367322, 0.860646, -0.227968], [0.280085, 0.672501, 0.047413],
                                [-0.011820, 0.042940, 0.968881]],
               "tritanopia": [[1.255528, -0.076749, -0.178779], [-0.078411, 0.930809, 0.147602],
                              [0.004733, 0.691367, 0.303900]],
               "normal vision": np.eye(3)}

    def seen(color, matrix):
        c = np.asarray(to_rgb(color))
        linear = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
        out = np.clip(np.asarray(matrix) @ linear, 0, 1)
        return rgb2lab(np.where(out <= 0.0031308, 12.92 * out, 1.055 * out ** (1 / 2.4) - 0.055)[None, None])

    others = [plotting.SPURIOUS_COLOR, plotting.POINT_COLOR, plotting.POINT_COLOR_3D, plotting.CURVE_COLOR,
              plotting.SURFACE_COLOR, figure.SPURIOUS_COLOR, figure.POINT_COLOR, "#8c8c8c", figure.SURFACE_COLOR,
              figure.CURVE_COLOR]
    assert figure.OUTLIER_COLOR == plotting.OUTLIER_COLOR  # the same colour in the figure and the viewer
    for vision, matrix in machado.items():
        gaps = [float(deltaE_ciede2000(seen(plotting.OUTLIER_COLOR, matrix), seen(c, matrix))[0, 0]) for c in others]
        assert min(gaps) > 15, (vision, gaps)  # 2-3 is a just noticeable difference
        white = float(deltaE_ciede2000(seen(plotting.OUTLIER_COLOR, matrix), seen("white", matrix))[0, 0])
        assert white > 25, vision


def test_outliers_in_their_own_colour_2d(fitted_ellipse):
    from ipfit.viz.plotting import OUTLIER_COLOR, POINT_COLOR, plot_result

    shape, result = fitted_ellipse
    points, indices, data = planted(shape, result)
    inliers = np.delete(points, indices, axis=0)
    fig = plot_result(data, points)
    panels = [ax for ax in fig.axes if ax.collections]  # the fits; the smoothness panel has no points
    assert len(panels) == len(fig.axes) - 1 >= 2
    for ax in panels:
        assert scatters_by_colour(ax) == {rgb(OUTLIER_COLOR): rows(points[indices]), rgb(POINT_COLOR): rows(inliers)}
        assert [t.get_text() for t in ax.get_legend().get_texts()] == ["outliers (20)"]
    # the same figure without the section: every point in the data colour, no legend
    fig = plot_result(result, points)
    assert scatters_by_colour(fig.axes[0]) == {rgb(POINT_COLOR): rows(points)} and fig.axes[0].get_legend() is None


def test_outliers_in_their_own_colour_3d(fitted_sphere):
    """Every outlier is drawn, over the surface; every other point beneath it."""
    from ipfit.viz.plotting import OUTLIER_COLOR, POINT_COLOR_3D, plot_result

    shape, result = fitted_sphere
    points, indices, data = planted(shape, result, n_outliers=30, seed=1)
    fig = plot_result(data, points, resolution=20)
    (ax,) = fig.axes
    drawn = scatters_by_colour(ax)
    assert set(drawn) == {rgb(OUTLIER_COLOR), rgb(POINT_COLOR_3D)}
    assert drawn[rgb(OUTLIER_COLOR)] == rows(points[indices])
    inliers = rows(np.delete(points, indices, axis=0))
    assert drawn[rgb(POINT_COLOR_3D)] == inliers
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["outliers (30)"]


@pytest.mark.parametrize("case", ["one row fewer", "recorded count", "index beyond the rows"])
def test_outliers_on_other_rows_warn_once_and_draw_all_as_data(fitted_ellipse, case):
    from ipfit import IpfitWarning
    from ipfit.viz.plotting import POINT_COLOR, plot_result

    shape, result = fitted_ellipse
    points, indices, data = planted(shape, result, n_points=case == "recorded count")
    if case == "recorded count":  # input.n_points says 140 were fitted: 145 rows are another cloud
        points = np.vstack([points, shape.points[:5]])
        why = "it fitted 140 points, but 145 points were given"
    elif case == "one row fewer":  # no input: the share (20 of 140) tells the rows apart
        points = points[np.arange(len(points)) != (indices[0] + 1)]
        why = "share of 0.142857 of the points it fitted, but 139 points were given"
    else:
        data["outliers"].pop("share")
        points = points[: indices[-1]]
        why = f"indices run up to {indices[-1]}, but {indices[-1]} points were given"
    with pytest.warns(IpfitWarning) as caught:
        fig = plot_result(data, points)
    assert len(caught) == 1 and why in str(caught[0].message)
    for ax in (a for a in fig.axes if a.collections):
        assert scatters_by_colour(ax) == {rgb(POINT_COLOR): rows(points)} and ax.get_legend() is None


def test_a_result_without_outliers_does_not_warn(fitted_ellipse, recwarn):
    from ipfit.viz.plotting import plot_result

    shape, result = fitted_ellipse
    points, _, data = planted(shape, result)
    data["outliers"] = {"mode": "none", "count": 0, "share": 0.0, "noise_scale": None, "indices": []}
    plot_result(data, points[:-3])  # no outliers to place: the row count does not matter
    plot_result(result, points[:-3])
    assert not [w for w in recwarn if "outliers" in str(w.message)]


def test_spurious_pieces_are_judged_against_the_inliers():
    """A zero-set oval through the outliers only is spurious for the fit: red once they are marked."""
    from matplotlib.colors import to_rgba

    from ipfit.viz.plotting import SPURIOUS_COLOR, plot_result
    from ipfit.zeroset.extract import extract_zero_set

    poly = _two_ovals()
    zs = extract_zero_set(poly, bounds=[[-2, 2], [-1, 1]])
    right = np.concatenate([c for c in zs.curves if c[:, 0].mean() > 0])[::3]
    left = np.concatenate([c for c in zs.curves if c[:, 0].mean() < 0])[::12]
    points = np.vstack([right, left])
    data = poly.to_dict()
    data["input"] = {"source": "two ovals", "n_points": len(points)}
    data["outliers"] = {"mode": "auto", "count": len(left), "share": len(left) / len(points), "noise_scale": None,
                        "indices": list(range(len(right), len(points)))}

    def left_is_red(result) -> bool:
        (ax,) = plot_result(result, points, margin=2.0).axes
        return {line.get_xdata().mean() < 0: to_rgba(line.get_color()) == to_rgba(SPURIOUS_COLOR)
                for line in ax.lines}[True]

    assert left_is_red(data)
    assert not left_is_red({k: v for k, v in data.items() if k != "outliers"})  # data near it: not spurious


def test_mesh_outliers_leave_the_faces_that_touch_them(fitted_sphere):
    """With faces, the data shown is sampled from the faces free of outliers; the outlier vertices are drawn apart."""
    import trimesh

    from ipfit.viz.plotting import OUTLIER_COLOR, POINT_COLOR_3D, plot_result

    _, result = fitted_sphere
    mesh = trimesh.creation.icosphere(subdivisions=2)
    vertices = np.array(mesh.vertices)
    outliers = np.array([0, 7, 30])
    vertices[outliers] *= 1.5  # pulled off the unit sphere
    data = json.loads(json.dumps(result))
    data["input"] = {"source": "icosphere", "n_points": len(vertices)}
    data["outliers"] = {"mode": "auto", "count": 3, "share": 3 / len(vertices), "noise_scale": None,
                        "indices": outliers.tolist()}
    (ax,) = plot_result(data, vertices, faces=mesh.faces, resolution=20).axes
    drawn = scatters_by_colour(ax)
    assert drawn[rgb(OUTLIER_COLOR)] == rows(vertices[outliers])
    radii = np.linalg.norm(np.array(sorted(drawn[rgb(POINT_COLOR_3D)])), axis=1)
    assert len(radii) > 300 and radii.max() < 1.0 + 1e-9  # samples of untouched faces: inside the unit sphere


def test_plot_points_takes_outliers_as_a_mask_or_indices():
    from ipfit.viz.plotting import OUTLIER_COLOR, POINT_COLOR, plot_points

    pts = synthetic.circle(50).points
    for outliers in ([7, 3], np.isin(np.arange(50), [3, 7])):
        ax = plot_points(pts, outliers=outliers)
        assert scatters_by_colour(ax) == {rgb(OUTLIER_COLOR): rows(pts[[3, 7]]),
                                          rgb(POINT_COLOR): rows(np.delete(pts, [3, 7], axis=0))}
        assert [t.get_text() for t in ax.get_legend().get_texts()] == ["outliers (2)"]
        close(ax)
    ax = plot_points(pts, outliers=[])  # none marked: as without
    assert scatters_by_colour(ax) == {rgb(POINT_COLOR): rows(pts)} and ax.get_legend() is None
    with pytest.raises(InvalidInputError, match=r"^outliers: expected 50 flags, one per point, or indices, got 49"):
        plot_points(pts, ax, outliers=np.ones(49, dtype=bool))
    with pytest.raises(InvalidInputError, match=r"^outliers: expected a mask of 50 flags or indices from 0 to 49, "
                                                r"got .* from 3 to 50\. Use"):
        plot_points(pts, ax, outliers=[3, 50])
    with pytest.raises(InvalidInputError, match="outliers: expected a mask"):
        plot_points(pts, ax, outliers=[0.5])
    close(ax)


def test_the_panels_share_one_measurement_of_the_data(monkeypatch):
    # Every degree's spurious pieces are judged against the same data: its samples and k-d tree
    # are built once for the figure, not once per panel (the same flags either way).
    import ipfit
    from ipfit.viz.plotting import plot_result
    from ipfit.zeroset import quality as quality_module

    boot = ipfit.load("boot")
    result = ipfit.fit_adaptive(boot.points, boot.normals, rng=0, max_degree=6)
    assert len(result.degrees) >= 2
    built = []
    original = quality_module.data_target

    def counted(*args, **kwargs):
        built.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(quality_module, "data_target", counted)
    fig = plot_result(result, boot.points)
    assert len(built) == 1
    assert sum(ax.name == "rectilinear" and bool(ax.lines) for ax in fig.axes) >= len(result.degrees)


def test_a_long_topology_note_stays_over_its_own_panel():
    # "2 loops nested (depths 0, 0) where the data's are nested (depths 0, 1)" is wider than a
    # panel: unwrapped, it ran into the next panel's title.
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from ipfit.viz.plotting import plot_result
    from ipfit.zeroset.topology import Topology, describe_mismatch

    shape = synthetic.ellipse()
    data = adaptive_result(shape.polynomial, {2: shape.polynomial, 4: synthetic.circle(radius=1.5).polynomial},
                           selected=2, comparisons=False)
    apart, nested = Topology(2, 2, nesting=(0, 0)), Topology(2, 2, nesting=(0, 1), source="contour")
    note = describe_mismatch(apart, nested)
    assert note.startswith("2 loops nested") and len(note) > 60
    for entry in data["degrees"]:
        entry["quality"] = {"topology": apart.to_dict(), "data_topology": nested.to_dict()}
    fig = plot_result(data, shape.points, resolution=64)
    FigureCanvasAgg(fig).draw()
    titles = [ax.title for ax in fig.axes]
    assert all(" ".join(t.get_text().split()).endswith(note) for t in titles[:2])
    boxes = [t.get_window_extent() for t in titles]
    for left, right in zip(boxes, boxes[1:]):  # the panels sit side by side in one row
        assert left.x1 <= right.x0
