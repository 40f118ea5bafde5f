"""The HTML viewer: decimation, spurious components, the figure's content, the page, the CLI,
and the page in a real headless browser (chromium + chromedriver through selenium)."""

from __future__ import annotations

import json
import re
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

import ipfit
from ipfit import ImplicitPolynomial, extract_zero_set, quality, write_points
from ipfit.cli import main
from ipfit.datasets import synthetic

from test_plotting import adaptive_result, planted

pytest.importorskip("plotly", reason="the viewer needs plotly (pip install 'ipfit[viewer]')")

from ipfit.viz import viewer  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def two_circles() -> ImplicitPolynomial:
    """(x² + y² − 1)((x − 5)² + y² − 1): two unit circles, at 0 and at (5, 0)."""
    a = synthetic.from_terms(2, 2, {(2, 0): 1, (0, 2): 1, (0, 0): -1})
    grid = np.random.default_rng(0).uniform(-2, 7, (400, 2))
    values = a(grid) * a(grid - [5.0, 0.0])
    from ipfit import basis

    coef = np.linalg.lstsq(basis.monomials(grid, basis.exponents(2, 4)), values, rcond=None)[0]
    return ImplicitPolynomial.from_coefficients(coef, dim=2)


@pytest.fixture(scope="module")
def ellipse_case():
    shape = synthetic.ellipse(120)
    circle = synthetic.circle(radius=1.5).polynomial
    return shape, adaptive_result(shape.polynomial, {2: shape.polynomial, 4: circle}, selected=2, comparisons=False)


@pytest.fixture(scope="module")
def torus_case():
    shape = synthetic.torus(600)
    flat = synthetic.ellipsoid(axes=(1.4, 1.4, 0.5)).polynomial
    return shape, adaptive_result(shape.polynomial, {2: flat, 4: shape.polynomial}, selected=4, comparisons=False)


# -- geometry -------------------------------------------------------------------------------

def test_decimate_stays_on_the_surface_and_keeps_labels():
    import trimesh

    a = trimesh.creation.icosphere(subdivisions=4)
    b = trimesh.creation.icosphere(subdivisions=4)
    vertices = np.vstack([a.vertices, b.vertices + [5.0, 0, 0]])
    faces = np.vstack([a.faces, b.faces + len(a.vertices)])
    labels = np.repeat([0, 1], len(a.faces))
    v, f, lab = viewer.decimate(vertices, faces, 800, labels)
    assert len(f) <= 800 and len(f) > 200
    centroids = v[f].mean(axis=1)
    assert np.array_equal(lab, (centroids[:, 0] > 2.5).astype(int))  # labels follow their faces
    radius = np.linalg.norm(v - np.where(v[:, :1] > 2.5, [5.0, 0, 0], 0.0), axis=1)
    assert np.abs(radius - 1).max() < 0.1
    area = trimesh.Trimesh(v, f, process=False).area
    assert area == pytest.approx(2 * 4 * np.pi, rel=0.1)
    # under the budget nothing changes
    v2, f2, _ = viewer.decimate(vertices, faces, len(faces))
    assert np.array_equal(f2, faces) and np.array_equal(v2, vertices)


def test_spurious_flags_mark_the_component_away_from_the_data():
    poly = two_circles()
    data = synthetic.circle(200).points  # on the circle at the origin only
    zs = extract_zero_set(poly, bounds=[[-2, 7], [-2, 2]], resolution=300)
    assert zs.n_components == 2
    flags = viewer.spurious_flags(zs, data)
    centres = np.array([c.mean(axis=0)[0] for c in zs.components()])
    assert np.array_equal(flags, centres > 2.5)
    assert int(flags.sum()) == quality(zs, data).n_spurious == 1
    # a recorded count that decides the answer is used as is
    assert not viewer.spurious_flags(zs, data, n_spurious=0).any()
    assert viewer.spurious_flags(zs, data, n_spurious=2).all()


# -- the figure -----------------------------------------------------------------------------

def test_figure_2d_slider_switches_degrees_and_hover_is_the_first_order_distance(ellipse_case):
    shape, data = ellipse_case
    fig = viewer.result_figure(data, shape.points)
    slider = fig.layout.sliders[0]
    assert [s.label for s in slider.steps] == ["2", "4"] and slider.active == 0  # the selected degree
    names = [t.name for t in fig.data]
    for step in slider.steps:
        update, layout, indices = step.args
        shown = {names[t] for t, v in zip(indices, update["visible"]) if v}
        assert f"degree {step.label}" in shown
        assert not any(n.startswith("degree ") and n != f"degree {step.label}" for n in shown if n)
        assert layout["title.text"].endswith(f"degree {step.label}")
        assert f"at degree {step.label}" in update["hovertemplate"][indices.index(0)]
    points = fig.data[0]
    assert points.name == "data points"
    custom = np.asarray(points.customdata, dtype=float)
    assert np.array_equal(custom[:, 0], np.arange(len(shape.points)))
    # degree 4 is the circle of radius 1.5, x² + y² − 2.25 up to scale: |f|/|∇f| = |r² − 2.25| / (2r)
    r = np.linalg.norm(shape.points, axis=1)
    assert np.allclose(custom[:, 2], np.abs(r ** 2 - 2.25) / (2 * r), rtol=1e-4, atol=1e-6)
    assert np.abs(custom[:, 1]).max() < 1e-5  # degree 2 is the ellipse itself


def test_figure_table_reason_and_per_degree_rule(ellipse_case):
    shape, data = ellipse_case
    data = json.loads(json.dumps(data))
    data["adaptive"] = {"reason": "criterion", "epsilon": 0.01, "rule": "paper"}
    data["degrees"][1]["rule"] = "gain 0.004 <= epsilon"
    fig = viewer.result_figure(data, shape.points, title="ellipse")
    tables = [t for t in fig.data if t.type == "table"]
    assert len(tables) == 2
    header = [h.replace("<b>", "").replace("</b>", "") for h in tables[0].header.values]
    assert header == ["degree", "dissimilarity", "smoothness", "distance", "F-score", "spurious", "seconds", "rule"]
    cells = tables[0].cells.values
    assert list(cells[0]) == ["2 ★", "4"] and list(cells[-1]) == ["", "gain 0.004 <= epsilon"]
    assert list(cells[2]) == [f"{0.84:.4g}", f"{0.88:.4g}"]
    # the row of the degree shown is highlighted, one table per degree
    assert [list(t.cells.fill.color[0]) for t in tables] == [[viewer.CURRENT_ROW, "white"],
                                                               ["white", viewer.CURRENT_ROW]]
    why = fig.layout.annotations[0].text
    assert "Selected degree 2" in why and "criterion" in why and "0.01" in why


def test_figure_marks_spurious_components_in_their_own_colour():
    # (r² − 1)(r² − 9): circles of radius 1 and 3; the data lie on the outer one only
    poly = synthetic.from_terms(2, 4, {(4, 0): 1, (2, 2): 2, (0, 4): 1, (2, 0): -10, (0, 2): -10, (0, 0): 9})
    data = adaptive_result(poly, {4: poly}, selected=4, comparisons=False)
    fig = viewer.result_figure(data, synthetic.circle(200, radius=3.0).points)
    curves = {t.name: t for t in fig.data if t.type == "scatter" and (t.name or "").startswith("degree")}
    assert set(curves) == {"degree 4", "degree 4 spurious"}
    spurious, clean = curves["degree 4 spurious"], curves["degree 4"]
    assert spurious.line.color == viewer.SPURIOUS_COLOR != clean.line.color
    radius = [np.nanmax(np.hypot(np.asarray(t.x, dtype=float), np.asarray(t.y, dtype=float))) for t in (spurious, clean)]
    assert radius == pytest.approx([1.0, 3.0], abs=0.02)


def test_figure_3d_meshes_normals_and_camera(torus_case):
    shape, data = torus_case
    fig = viewer.result_figure(data, shape.points, normals=shape.normals, resolution=40, max_faces=1500, up="y")
    meshes = [t for t in fig.data if t.type == "mesh3d"]
    assert [m.name for m in meshes] == ["degree 2", "degree 4"]
    assert [m.visible for m in meshes] == [False, True]
    for mesh in meshes:
        assert 0 < len(mesh.i) <= 1500
    torus = meshes[1]
    v = np.column_stack([np.asarray(torus.x), np.asarray(torus.y), np.asarray(torus.z)]).astype(float)
    assert np.abs(shape.polynomial.taubin_distance(v)).max() < 0.1  # decimated, still on the torus
    normals = next(t for t in fig.data if t.name == "normals")
    assert normals.visible == "legendonly"
    seg = np.column_stack([np.asarray(normals.x), np.asarray(normals.y), np.asarray(normals.z)]).astype(float)
    starts, ends = seg[0::3], seg[1::3]
    assert np.isnan(seg[2::3]).all()
    lengths = np.linalg.norm(ends - starts, axis=1)
    assert np.allclose(lengths, lengths[0], rtol=1e-3)
    assert fig.layout.scene.camera.up.y == 1 and fig.layout.scene.camera.up.z == 0


def test_figure_of_an_adaptive_result_object():
    from ipfit import fit_adaptive

    shape = synthetic.ellipse(150)
    result = fit_adaptive(shape.points, shape.normals, method="3l", max_degree=4, epsilon=-1.0)
    fig = viewer.result_figure(result, shape.points)
    assert [s.label for s in fig.layout.sliders[0].steps] == [str(d.degree) for d in result.degrees]
    assert fig.layout.sliders[0].steps[fig.layout.sliders[0].active].label == str(result.selected_degree)
    assert "F-score" in [t.name for t in fig.data]  # the geometric rule measured every degree


def test_figure_without_points_uses_recorded_bounds(torus_case):
    shape, data = torus_case
    data = dict(data, bounds=np.column_stack([shape.points.min(0), shape.points.max(0)]).tolist())
    fig = viewer.result_figure(data, resolution=30)
    assert [t.name for t in fig.data if t.type == "mesh3d"] == ["degree 2", "degree 4"]
    assert not any(t.name == "data points" for t in fig.data)
    assert fig.layout.scene.xaxis.range[0] < shape.points[:, 0].min()


@pytest.fixture(scope="module")
def planted_ellipse():
    """A real result (fit_adaptive's to_dict, 3L, degrees 2 and 4) and 20 planted outliers."""
    shape = synthetic.ellipse(120)
    result = ipfit.fit_adaptive(shape.points, shape.normals, method="3l", max_degree=4, rule="geometric").to_dict()
    return planted(shape, result)


def _xyz(trace) -> np.ndarray:
    axes = [trace.x, trace.y] + ([trace.z] if trace.type == "scatter3d" else [])
    return np.column_stack([np.asarray(a, dtype=np.float32) for a in axes])


def test_figure_outliers_are_a_trace_of_their_own(planted_ellipse):
    points, indices, data = planted_ellipse
    fig = viewer.result_figure(data, points)
    traces = {t.name: t for t in fig.data}
    outliers, inliers = traces["outliers (20)"], traces["data points"]
    assert outliers.marker.color == viewer.OUTLIER_COLOR != inliers.marker.color
    assert outliers.showlegend is not False and outliers.visible in (None, True)  # listed, so a click hides it
    kept = np.setdiff1d(np.arange(len(points)), indices)
    np.testing.assert_array_equal(_xyz(outliers), points[indices].astype(np.float32))
    np.testing.assert_array_equal(_xyz(inliers), points[kept].astype(np.float32))
    # hovering shows the point's index in the data, and |f|/|grad f| at the degree shown, in either trace
    np.testing.assert_array_equal(np.asarray(outliers.customdata)[:, 0], indices)
    np.testing.assert_array_equal(np.asarray(inliers.customdata)[:, 0], kept)
    names = [t.name for t in fig.data]
    for step in fig.layout.sliders[0].steps:
        update, _, switched = step.args
        for name in ("data points", "outliers (20)"):
            at = switched.index(names.index(name))
            assert update["visible"][at] and f"at degree {step.label}:" in update["hovertemplate"][at]


def test_figure_3d_outliers(torus_case):
    shape, data = torus_case
    points, indices, data = planted(shape, data, n_outliers=25, seed=3)
    fig = viewer.result_figure(data, points, resolution=24, max_faces=800)
    (outliers,) = [t for t in fig.data if t.name == "outliers (25)"]
    assert outliers.type == "scatter3d" and outliers.marker.color == viewer.OUTLIER_COLOR
    np.testing.assert_array_equal(_xyz(outliers), points[indices].astype(np.float32))
    (inliers,) = [t for t in fig.data if t.name == "data points"]
    assert len(inliers.x) == len(points) - 25


def test_figure_with_other_rows_warns_and_draws_all_as_data(planted_ellipse):
    points, _, data = planted_ellipse
    with pytest.warns(ipfit.IpfitWarning, match="it fitted 140 points, but 100 points were given") as caught:
        fig = viewer.result_figure(data, points[:100])
    assert len(caught) == 1
    assert [t.name for t in fig.data if t.type == "scatter" and t.mode == "markers"][:1] == ["data points"]
    assert not any((t.name or "").startswith("outliers") for t in fig.data)
    np.testing.assert_array_equal(_xyz(fig.data[0]), points[:100].astype(np.float32))


# -- HTML and the command line --------------------------------------------------------------

def test_page_is_self_contained_and_div_for_notebooks(ellipse_case, tmp_path):
    shape, data = ellipse_case
    page = viewer.to_html(data, shape.points)
    assert page.startswith("<!DOCTYPE html>")
    assert not re.search(r"<script[^>]*\bsrc\s*=", page, re.IGNORECASE)  # nothing loaded from anywhere
    assert "<script src=\"http" not in page
    assert "Plotly.newPlot" in page and len(page) > 3_000_000  # plotly.js inlined
    div = viewer.to_html(data, shape.points, full_html=False)
    assert div.startswith("<div") and "<html" not in div
    with pytest.raises(ValueError, match="path: expected a file name ending in .html"):
        viewer.write_html(data, shape.points, tmp_path / "view.png")
    with pytest.raises(ValueError, match="Create"):
        viewer.write_html(data, shape.points, tmp_path / "missing" / "view.html")
    assert list(tmp_path.iterdir()) == []


def test_cli_view(torus_case, tmp_path, capsys):
    shape, data = torus_case
    result = tmp_path / "torus.json"
    data = dict(data, input={"source": str(tmp_path / "torus.ply")})
    result.write_text(json.dumps(data))
    write_points(tmp_path / "torus.ply", shape.points, shape.normals)
    assert main(["view", str(result), "--max-faces", "800"]) == 0  # default: beside the result, recorded data
    page = (tmp_path / "torus.html").read_text(encoding="utf-8")
    assert '"name":"data points"' in page and '"name":"normals"' in page
    assert "torus.html" in capsys.readouterr().out
    out = tmp_path / "v.html"
    assert main(["view", str(result), "--no-points", "--no-normals", "-o", str(out), "--max-faces", "800"]) == 0
    assert '"name":"data points"' not in out.read_text(encoding="utf-8")


def test_cli_view_outliers_and_a_warning_for_other_data(planted_ellipse, tmp_path, capsys):
    points, _, data = planted_ellipse
    write_points(tmp_path / "cloud.csv", points)
    result = tmp_path / "cloud.json"
    result.write_text(json.dumps(dict(data, input={"source": str(tmp_path / "cloud.csv"), "n_points": len(points)})))
    assert main(["view", str(result), "-o", str(tmp_path / "a.html")]) == 0  # the recorded data: the fitted points
    assert '"name":"outliers (20)"' in (tmp_path / "a.html").read_text(encoding="utf-8")
    assert capsys.readouterr().err == ""
    write_points(tmp_path / "other.csv", points[:-1])
    assert main(["view", str(result), "--points", str(tmp_path / "other.csv"), "-o", str(tmp_path / "b.html")]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "outliers not marked: it fitted 140 points, but 139 points were given" in err
    assert '"name":"outliers' not in (tmp_path / "b.html").read_text(encoding="utf-8")


@pytest.mark.parametrize("argv, match", [
    (["--points", "{tmp}/flat.csv"], "expected 3D points"),
    (["-o", "{tmp}/v.png"], "ending in .html"),
    (["-o", "{tmp}/no/v.html"], "Create"),
])
def test_cli_view_errors_one_line_no_file(torus_case, tmp_path, capsys, argv, match):
    shape, data = torus_case
    result = tmp_path / "torus.json"
    result.write_text(json.dumps(data))
    write_points(tmp_path / "flat.csv", shape.points[:, :2])
    before = set(tmp_path.iterdir())
    assert main(["view", str(result)] + [a.replace("{tmp}", str(tmp_path)) for a in argv]) == 2
    err = capsys.readouterr().err
    assert match in err and err.count("\n") == 1 and "Traceback" not in err
    assert set(tmp_path.iterdir()) == before


def test_cli_view_missing_result(tmp_path, capsys):
    assert main(["view", str(tmp_path / "nothing.json")]) == 2
    assert "no such file" in capsys.readouterr().err


# -- a real browser -------------------------------------------------------------------------

def _browser_paths() -> tuple[str, str]:
    try:
        import selenium  # noqa: F401
    except ImportError:
        pytest.skip("browser test skipped: selenium is not installed (pip install 'ipfit[test]')")
    browser = next((p for p in map(shutil.which, ("chromium", "chromium-browser", "google-chrome")) if p), None)
    driver = shutil.which("chromedriver")
    if not browser or not driver:
        pytest.skip("browser test skipped: no chromium/chromedriver on PATH "
                    "(apt-get install chromium chromium-driver; .ci/run installs them)")
    return browser, driver


@pytest.fixture(scope="module")
def browser():
    binary, driver_path = _browser_paths()
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = binary
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1200,760",
                "--enable-unsafe-swiftshader", "--hide-scrollbars"):
        options.add_argument(arg)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(driver_path), options=options)
    yield driver
    driver.quit()


def _screenshot(driver) -> np.ndarray:
    from io import BytesIO

    from PIL import Image

    return np.asarray(Image.open(BytesIO(driver.get_screenshot_as_png())).convert("RGB"), dtype=np.int16)


def _plot_area(image: np.ndarray) -> np.ndarray:
    h, w, _ = image.shape
    return image[int(0.08 * h):int(0.8 * h), : int(0.58 * w)]  # the scene / axes, without the slider


def _blue_fraction(image: np.ndarray) -> float:
    # the zero set is drawn in blues; the points, axes and background are greys
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    return float(np.mean((b - r > 40) & (b - g > 15)))


def _wait_for(condition, what: str, timeout: float = 20.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value is not None and value is not False:
            return value
        time.sleep(0.1)
    pytest.fail(f"timed out waiting for {what}")


def _plot(driver, expression: str):
    return driver.execute_script(f"var gd = document.querySelector('.js-plotly-plot'); return {expression};")


def _drawn(driver):
    # WebGL draws a frame or two after the page reports ready: poll the pixels, not a clock
    area = _plot_area(_screenshot(driver))
    return area if area.std() > 10 and _blue_fraction(area) > 0.002 else None


def _click_slider(driver, fraction: float) -> None:
    from selenium.webdriver.common.action_chains import ActionChains

    box = driver.execute_script("var r = document.querySelector('.slider-rail-touch-rect')"
                                ".getBoundingClientRect(); return [r.left, r.top, r.width, r.height];")
    x, y = int(box[0] + fraction * box[2]), int(box[1] + box[3] / 2)
    ActionChains(driver).move_by_offset(x, y).click().move_by_offset(-x, -y).perform()


@pytest.mark.parametrize("case", ["ellipse_case", "torus_case"])
def test_page_in_a_headless_browser(browser, case, request, tmp_path):
    shape, data = request.getfixturevalue(case)
    path = tmp_path / "view.html"
    viewer.write_html(data, shape.points, path, resolution=48 if shape.points.shape[1] == 3 else None,
                      max_faces=4000)
    browser.get(path.resolve().as_uri())
    _wait_for(lambda: _plot(browser, "!!(gd && gd._fullLayout && gd.layout.sliders)"), "plotly to draw")
    before = _wait_for(lambda: _drawn(browser), "a non-blank plot (zero set drawn in blue)")
    assert [e for e in browser.get_log("browser") if e["level"] == "SEVERE"] == []

    active = _plot(browser, "gd.layout.sliders[0].active")
    other = 4 if active == 0 else 2
    _click_slider(browser, 0.97 if active == 0 else 0.03)  # the other end of the slider
    _wait_for(lambda: _plot(browser, "gd.layout.title.text").endswith(f"degree {other}"), "the slider's update")

    def changed():
        after = _drawn(browser)
        if after is None:
            return None
        fraction = float(np.mean(np.abs(after - before).sum(axis=2) > 30))
        return fraction if fraction > 0.005 else None

    _wait_for(changed, "the drawn zero set to change after moving the slider", timeout=10)
    if shape.points.shape[1] == 2:  # plotly can hover 2D points from script; 3D needs a real mouse
        label = _plot(browser, "(Plotly.Fx.hover(gd, [{curveNumber: 0, pointNumber: 3}]), "
                               "Array.from(document.querySelectorAll('.hoverlayer text')).map(t => t.textContent)"
                               ".join(' '))")
        assert label.startswith("point 3") and f"at degree {other}:" in label
    assert [e for e in browser.get_log("browser") if e["level"] == "SEVERE"] == []


# -- the full bunny -------------------------------------------------------------------------

@pytest.mark.slow
def test_bunny_page_size_and_spurious_counts(tmp_path):
    from ipfit import load_dataset
    from ipfit.datasets.bundled import dataset_faces

    data = json.loads((REPO / "docs" / "datasets" / "bunny.json").read_text())
    points = load_dataset("bunny").points
    fig = viewer.result_figure(data, points, faces=dataset_faces("bunny"), up="y")
    for entry in data["degrees"]:
        spurious = [t for t in fig.data if t.name == f"degree {entry['degree']} spurious"]
        assert bool(spurious) == (entry["quality"]["n_spurious"] > 0)
    path = tmp_path / "bunny.html"
    viewer.write_html(data, points, path, faces=dataset_faces("bunny"), up="y")
    assert path.stat().st_size < 10e6


def test_fit_html_writes_the_viewer_beside_the_other_outputs(tmp_path):
    from ipfit.cli import main

    code = main(["fit", "boot", "-o", str(tmp_path / "boot"), "--method", "3l", "--max-degree", "4", "--quiet",
                 "--html"])
    assert code == 0
    page = (tmp_path / "boot.html").read_text(encoding="utf-8")
    assert "plotly" in page.lower() and not re.search(r"<script[^>]+src=[\"']https?:", page)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["boot.csv", "boot.html", "boot.json", "boot.png", "boot.svg"]


def test_a_result_displays_itself_in_a_notebook():
    from ipfit.datasets import synthetic

    shape = synthetic.ellipse(120, a=2.0, b=1.0)
    result = ipfit.fit_adaptive(shape.points, shape.normals, method="3l", max_degree=4)
    html = result._repr_html_()
    assert html.lstrip().startswith("<div") and "<html" not in html[:200].lower()
    figure = result.show(shape.points)
    assert len(figure.data) > 0 and len(figure.layout.sliders) == 1


def _amber_fraction(image: np.ndarray) -> float:
    # OUTLIER_COLOR (#ffb000): nothing else on the page is a saturated yellow (the spurious red has little green)
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    return float(np.mean((r > 200) & (g > 130) & (g < 215) & (b < 90)))


def test_outliers_toggle_in_the_legend_in_a_headless_browser(browser, planted_ellipse, tmp_path):
    points, _, data = planted_ellipse
    path = tmp_path / "view.html"
    viewer.write_html(data, points, path)
    browser.get(path.resolve().as_uri())
    _wait_for(lambda: _plot(browser, "!!(gd && gd._fullLayout && gd.layout.sliders)"), "plotly to draw")
    _wait_for(lambda: _amber_fraction(_plot_area(_screenshot(browser))) > 1e-4, "the outliers drawn in amber")
    item = browser.execute_script("return Array.from(document.querySelectorAll('.legend .traces'))"
                                  ".find(t => t.textContent === 'outliers (20)').querySelector('.legendtoggle');")
    item.click()
    assert _wait_for(lambda: _plot(browser, "gd.data.find(t => t.name === 'outliers (20)').visible"),
                     "the legend click") == "legendonly"
    _wait_for(lambda: _amber_fraction(_plot_area(_screenshot(browser))) == 0, "the outliers hidden")
    assert [e for e in browser.get_log("browser") if e["level"] == "SEVERE"] == []
