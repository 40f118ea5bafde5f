"""3D result figures, on pictures rendered with matplotlib's Agg: larger surface panels, the data
beneath the surface (see-through, never over it), and a trimmed surface drawn lighter than the
part near the data."""

from __future__ import annotations

import math

import numpy as np
import pytest
from mpl_toolkits.mplot3d.art3d import Path3DCollection, Poly3DCollection
from scipy.spatial import cKDTree
from test_plotting import adaptive_result

from ipfit.datasets import synthetic
from ipfit.viz.plotting import TRIMMED_ALPHA, plot_result, plot_surface
from ipfit.zeroset.extract import extract_zero_set
from ipfit.zeroset.trim import default_trim_distance, trim_mask


def picture(fig) -> np.ndarray:
    """The figure rendered by Agg: (height, width, 3) floats in [0, 1]."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].astype(float) / 255


def panel(image: np.ndarray, fig, ax) -> np.ndarray:
    """The pixels of one axes."""
    box = ax.get_window_extent()
    height = image.shape[0]
    return image[height - int(box.y1):height - int(box.y0), int(box.x0):int(box.x1)]


def ink_width(pixels: np.ndarray) -> float:
    """Share of a panel's width that holds anything drawn (not white)."""
    cols = np.flatnonzero((pixels.min(axis=2) < 0.9).any(axis=0))
    return 0.0 if cols.size == 0 else (cols.max() - cols.min() + 1) / pixels.shape[1]


@pytest.fixture(scope="module")
def torus_result():
    shape = synthetic.torus(800)
    sphere = synthetic.ellipsoid(axes=(1.4, 1.4, 0.5)).polynomial
    return shape, adaptive_result(shape.polynomial, {2: sphere, 4: shape.polynomial}, selected=4)


def test_surface_panels_are_larger_than_curve_panels_and_filled(torus_result):
    shape, result = torus_result
    fig = plot_result(result, shape.points, resolution=32)
    image = picture(fig)
    surfaces = [ax for ax in fig.axes if ax.name == "3d"]
    assert len(surfaces) == 4 and len(fig.axes) == 5  # 2 degrees + classic + 3L, and the smoothness curve
    columns = {round(ax.get_position().x0, 3) for ax in fig.axes}
    assert len(columns) <= 3  # at most 3 panels a row
    ellipse = synthetic.ellipse()
    flat = plot_result(adaptive_result(ellipse.polynomial, {2: ellipse.polynomial, 4: ellipse.polynomial}, 2),
                       ellipse.points)
    curve_width = flat.axes[0].get_window_extent().width / flat.dpi
    for ax in surfaces:
        width = ax.get_window_extent().width / fig.dpi
        assert width > 1.2 * curve_width and width > 4.0  # inches
        # the surface itself spans most of its panel (3D axes keep wide empty margins otherwise)
        assert ink_width(panel(image, fig, ax)) > 0.6


def test_the_data_is_beneath_the_surface_not_over_it(torus_result):
    shape, result = torus_result
    with_points = plot_result(result, shape.points, resolution=32)
    # the same box without the points: the result's record of the data's bounds
    bounds = np.column_stack([shape.points.min(axis=0), shape.points.max(axis=0)]).tolist()
    without = plot_result({**result, "bounds": bounds}, resolution=32)
    for ax in with_points.axes:
        if ax.name != "3d":
            continue
        (cloud,) = [c for c in ax.collections if isinstance(c, Path3DCollection)]
        surface = max((c for c in ax.collections if isinstance(c, Poly3DCollection)), key=lambda c: c.get_zorder())
        assert len(cloud._offsets3d[0]) == len(shape.points)  # every point, not only the front
        assert cloud.get_alpha() < 1 and cloud.get_zorder() < surface.get_zorder()
    # On the rendered picture: the torus's own points lie on its surface, so the surface hides them
    # all: the selected panel (the exact torus) looks the same with and without them ...
    a, b = picture(with_points), picture(without)
    selected = with_points.axes[1]
    assert "(selected)" in selected.get_title()
    drawn_a, drawn_b = panel(a, with_points, selected), panel(b, without, without.axes[1])
    surface_pixels = (drawn_b.min(axis=2) < 0.9).sum()
    changed = np.abs(drawn_a - drawn_b).max(axis=2) > 0.05
    assert changed.sum() < 0.01 * surface_pixels
    # ... while points drawn over it (plot_surface's "front" style) change much of it
    front = plot_surface(shape.polynomial, shape.points, resolution=32, show_points=True, axis_off=True)
    plain = plot_surface(shape.polynomial, shape.points, resolution=32, axis_off=True)
    over = np.abs(picture(front.figure) - picture(plain.figure)).max(axis=2) > 0.05
    assert over.sum() > 0.05 * (picture(plain.figure).min(axis=2) < 0.9).sum()


def test_points_off_the_surface_show_see_through():
    # a sphere's polynomial against points on a larger sphere: they stick out around it
    poly = synthetic.sphere().polynomial
    outside = synthetic.sphere(600, radius=1.3).points
    ax = plot_surface(poly, outside, bounds=[[-1.6, 1.6]] * 3, resolution=32, show_points="under", axis_off=True)
    (cloud,) = [c for c in ax.collections if isinstance(c, Path3DCollection)]
    assert cloud.get_alpha() < 0.5 and len(cloud._offsets3d[0]) == 600
    plain = plot_surface(poly, outside, bounds=[[-1.6, 1.6]] * 3, resolution=32, axis_off=True)
    image, background = picture(ax.figure).min(axis=2), picture(plain.figure).min(axis=2)
    # the points around the sphere's outline (white without them) are drawn see-through: lighter
    # than their colour at full opacity (0.19)
    ring = (background > 0.99) & (image < 0.95)
    assert ring.sum() > 200 and np.median(image[ring]) > 0.5
    with pytest.raises(Exception, match="show_points"):
        plot_surface(poly, outside, resolution=16, show_points="beside")


def dome_points(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    z = rng.uniform(-0.2, 1.0, n)
    phi = rng.uniform(0, 2 * np.pi, n)
    r = np.sqrt(1 - z * z)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_trimmed_part_is_drawn_lighter_than_the_part_near_the_data(seed):
    points = dome_points(800, seed)
    poly = synthetic.sphere().polynomial
    distance = default_trim_distance(points)
    fig = plot_result(poly, points, trim=distance, resolution=40)
    (ax,) = fig.axes
    (surface,) = [c for c in ax.collections if isinstance(c, Poly3DCollection)]
    colors = surface.get_facecolor()
    # the same faces the trim leaves out of the zero set drawn (the figure's grid and box)
    zs = extract_zero_set(poly, points=points, resolution=40)
    faint = ~trim_mask(zs, points, distance)
    assert len(colors) == len(faint) and 0.1 < faint.mean() < 0.6
    # (matplotlib keeps the colours in its drawing order: compare the two sets of faces, not rows)
    light = colors[:, 3] == TRIMMED_ALPHA
    assert light.sum() == faint.sum() and np.all(colors[~light, 3] == 1.0)
    luminance = colors[:, :3] @ [0.2126, 0.7152, 0.0722]
    assert luminance[light].min() > luminance[~light].mean()
    assert luminance[light].mean() > luminance[~light].mean() + 0.2
    # the faces left out are those with a vertex beyond the trim distance, below the data's rim (z = -0.2)
    far = cKDTree(points).query(zs.vertices)[0] > distance
    assert np.all(far[zs.faces[faint]].any(axis=1))
    assert np.mean(zs.vertices[zs.faces[faint]][:, :, 2].max(axis=1) < -0.2 + distance) > 0.95
    # On the picture: against the untrimmed figure, what changed got lighter, in the lower part
    whole = plot_result(poly, points, resolution=40)
    a, b = picture(fig), picture(whole)
    changed = np.abs(a - b).max(axis=2) > 0.05
    assert changed.sum() > 500
    assert a[changed].mean() > b[changed].mean() + 0.1
    rows = np.flatnonzero((b.min(axis=2) < 0.9).any(axis=1))
    middle = (rows.min() + rows.max()) / 2
    assert np.flatnonzero(changed.any(axis=1)).min() > middle - 0.1 * (rows.max() - rows.min())


def test_a_closed_shape_has_nothing_light(torus_result):
    shape, _ = torus_result
    fig = plot_result(shape.polynomial, shape.points, trim=default_trim_distance(shape.points), resolution=32)
    (surface,) = [c for c in fig.axes[0].collections if isinstance(c, Poly3DCollection)]
    assert np.all(surface.get_facecolor()[:, 3] == 1.0)
    assert math.isclose(fig.get_size_inches()[0], 4.8)
