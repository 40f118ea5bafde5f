"""Trimming an extracted zero set to the data (``ZeroSet.trimmed``, ``ipfit fit/mesh --trim``).

The open shape is a cup made here: the side wall x² + y² = 1, 0 ≤ z ≤ 2, and the bottom
disk z = 0, with no lid. A polynomial's zero set cannot be open, so the fit closes the cup;
trimming must take the lid off and leave the polynomial alone.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

import ipfit
from ipfit.datasets import synthetic
from ipfit.exceptions import InvalidInputError
from ipfit.zeroset.trim import default_gap_distance, default_trim_distance, trim_mask, trim_zero_set

from test_cli_mesh_plot_score import run

CUP_HEIGHT = 2.0


def cup(n: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """Points and outward normals spread evenly by area over the open cup."""
    n_side = round(n * 4 / 5)  # side 4π, bottom π
    theta, z = rng.uniform(0, 2 * np.pi, n_side), rng.uniform(0, CUP_HEIGHT, n_side)
    side = np.column_stack([np.cos(theta), np.sin(theta), z])
    r, phi = np.sqrt(rng.uniform(0, 1, n - n_side)), rng.uniform(0, 2 * np.pi, n - n_side)
    bottom = np.column_stack([r * np.cos(phi), r * np.sin(phi), np.zeros(n - n_side)])
    normals = np.vstack([side * [1, 1, 0], np.tile([0.0, 0.0, -1.0], (n - n_side, 1))])
    return np.vstack([side, bottom]), normals


def distance_to_cup(p: np.ndarray) -> np.ndarray:
    """Exact distance to the open cup's surface (side wall and bottom disk)."""
    rho, z = np.hypot(p[:, 0], p[:, 1]), p[:, 2]
    to_wall = np.hypot(rho - 1, z - np.clip(z, 0, CUP_HEIGHT))
    to_bottom = np.hypot(np.maximum(rho - 1, 0), z)
    return np.minimum(to_wall, to_bottom)


def areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


@pytest.fixture
def fitted_cup(rng):
    points, normals = cup(3000, rng)
    poly = ipfit.fit_3l(points, normals, 4)
    return points, poly, ipfit.extract_zero_set(poly, points=points, resolution=64)


# -- the library ------------------------------------------------------------------------------

def test_trimming_the_cup_raises_precision_and_keeps_the_polynomial(fitted_cup):
    points, poly, zs = fitted_cup
    coefficients = poly.coefficients.copy()
    assert zs.closed  # the fit closes the cup: a lid where there is no data
    trimmed = zs.trimmed(points)
    distance = trimmed.trim.distance
    assert distance == default_trim_distance(points)
    before, after = ipfit.quality(zs, points), ipfit.quality(trimmed, points)
    assert after.precision > before.precision + 0.1
    assert after.recall >= before.recall - 0.005  # nothing the data needs went
    gap = trimmed.trim.gap
    assert gap == default_gap_distance(points) > distance
    # every kept face's vertices are within the gap distance of a data point (an independent k-d
    # tree): within the trim distance, or in a hole between samples that gets no farther
    assert cKDTree(points).query(trimmed.vertices)[0].max() <= gap
    assert trimmed.vertices[:, 2].max() <= CUP_HEIGHT + distance  # the lid is gone, to the trim distance
    assert not trimmed.closed and trimmed.trim.removed_faces > 0
    # every face whose three vertices are within the distance is kept, and no face with a vertex
    # beyond the gap distance
    d = cKDTree(points).query(zs.vertices)[0]
    keep = trim_mask(zs, points)
    assert np.all(keep[(d <= distance)[zs.faces].all(axis=1)]) and not np.any(keep[(d > gap)[zs.faces].any(axis=1)])
    assert len(trimmed.faces) == keep.sum()
    area = areas(zs.vertices, zs.faces)
    assert math.isclose(areas(trimmed.vertices, trimmed.faces).sum(), area[keep].sum(), rel_tol=1e-9)
    assert math.isclose(trimmed.trim.removed_share, area[~keep].sum() / area.sum(), rel_tol=1e-9)
    # no dangling vertices, and the polynomial is the same, bit for bit
    assert np.array_equal(np.unique(trimmed.faces), np.arange(len(trimmed.vertices)))
    assert trimmed.polynomial is poly and np.array_equal(poly.coefficients, coefficients)


def test_trimming_to_a_mesh_measures_to_its_faces_not_its_vertices(fitted_cup):
    # A coarse open cup mesh: its wall has vertices only on the rims, 2 apart.
    trimesh = pytest.importorskip("trimesh")
    _, _, zs = fitted_cup
    mesh = trimesh.creation.cylinder(radius=1.0, height=CUP_HEIGHT, sections=64)
    vertices = np.asarray(mesh.vertices) + [0, 0, CUP_HEIGHT / 2]
    faces = np.asarray(mesh.faces)
    lid = np.isclose(vertices[faces][:, :, 2], CUP_HEIGHT).all(axis=1)
    faces = faces[~lid]
    distance = 0.15
    to_faces = zs.trimmed(vertices, distance, faces=faces)
    to_vertices = zs.trimmed(vertices, distance)
    assert to_faces.trim.reference == "faces" and to_vertices.trim.reference == "points"
    # polygon vs circle (1 - cos(π/64) < 0.0013) and the fit's own error are far below the distance
    assert distance_to_cup(to_faces.vertices).max() <= distance + 0.0013
    assert to_faces.vertices[:, 2].max() <= CUP_HEIGHT + distance
    # the wall between the rims stays: only the lid (π of the ~5π + lid) goes
    assert 0.1 < to_faces.trim.removed_share < 0.25
    assert to_vertices.trim.removed_share > to_faces.trim.removed_share + 0.3


def test_a_closed_shape_loses_nothing_at_the_default_distance(rng):
    shape = synthetic.sphere(2000, rng=rng)
    poly = ipfit.fit_3l(shape.points, shape.normals, 2)
    zs = ipfit.extract_zero_set(poly, points=shape.points, resolution=64)
    trimmed = zs.trimmed(shape.points)
    assert trimmed.trim.removed_share < 0.001  # stated bound: under 0.1 % of the area
    assert trimmed.closed == (trimmed.trim.removed_faces == 0)


def test_hemisphere_data_keeps_the_analytic_cap():
    # Data on the lower half of the unit sphere: a point at angle α above the equator is
    # 2 sin(α/2) from the rim, so the kept cap reaches sin α = sin(2 asin(d/2)); its area
    # is 2π(1 + sin α), and the removed share (1 - sin α) / 2.
    shape = synthetic.sphere(40000)
    bowl = shape.points[shape.points[:, 2] < 0]
    zs = ipfit.extract_zero_set(shape.polynomial, points=shape.points, resolution=96)
    distance = 0.3
    trimmed = zs.trimmed(bowl, distance)
    sin_alpha = math.sin(2 * math.asin(distance / 2))
    expected = (1 - sin_alpha) / 2
    # Data points are no nearer than the hemisphere, so no more is kept than the cap; a face
    # crossing the cut goes whole, a band at most one face (√3 grid steps) wide along the
    # cut circle, of length 2π cos α, out of the sphere's 4π.
    band = 2 * math.pi * math.sqrt(1 - sin_alpha**2) * math.sqrt(3) * zs.step / (4 * math.pi)
    assert expected - 0.003 < trimmed.trim.removed_share < expected + band
    assert trimmed.n_components == 1


def test_a_2d_curve_is_cut_into_the_pieces_near_the_data():
    zs = ipfit.extract_zero_set(synthetic.circle().polynomial, bounds=[[-1.5, 1.5], [-1.5, 1.5]])
    t = np.linspace(-np.pi / 2, np.pi / 2, 2000)
    right = np.column_stack([np.cos(t), np.sin(t)])
    distance = 0.2
    trimmed = trim_zero_set(zs, right, distance)
    expected = (np.pi - 4 * math.asin(distance / 2)) / (2 * np.pi)  # the arcs beyond the chord 2 sin(φ/2) = d
    assert abs(trimmed.trim.removed_share - expected) < 0.005
    assert len(trimmed.curves) == 1 and trimmed.curve_closed == (False,)  # one arc across the loop's seam
    assert cKDTree(right).query(np.concatenate(trimmed.curves))[0].max() <= distance
    assert "curve length" in trimmed.trim.describe()
    # two runs of data on opposite sides: two arcs
    top_bottom = np.concatenate([right[np.abs(right[:, 1]) > 0.9], -right[np.abs(right[:, 1]) > 0.9]])
    assert len(trim_zero_set(zs, top_bottom, 0.1).curves) == 2


@pytest.mark.parametrize("distance", [-1.0, 0.0, np.nan, np.inf, "abc"])
def test_bad_distances_are_refused(fitted_cup, distance):
    points, _, zs = fitted_cup
    with pytest.raises(InvalidInputError, match="distance"):
        zs.trimmed(points, distance)


def test_bad_data_is_refused(fitted_cup):
    points, _, zs = fitted_cup
    with pytest.raises(InvalidInputError, match="points"):
        zs.trimmed(points[:, :2])
    with pytest.raises(InvalidInputError, match="zero_set"):
        trim_zero_set(zs.polynomial, points)
    circle = ipfit.extract_zero_set(synthetic.circle().polynomial, bounds=[[-1.5, 1.5], [-1.5, 1.5]])
    with pytest.raises(InvalidInputError, match="faces"):
        circle.trimmed(synthetic.circle().points, faces=[[0, 1, 2]])
    with pytest.raises(InvalidInputError, match="identical"):
        zs.trimmed(np.ones((5, 3)))


# -- the command line ---------------------------------------------------------------------------

@pytest.fixture
def cup_file(tmp_path, rng):
    points, normals = cup(2000, rng)
    return ipfit.write_points(tmp_path / "cup.ply", points, normals), points


def fit_cup(capsys, path, tmp_path) -> Path:
    """``ipfit fit`` of the cup file at degree 4 (3L), the JSON alone; returns its path."""
    code, _, err = run(capsys, ["fit", path, "--degree", "4", "--method", "3l", "--no-picture", "--no-zero-set",
                                "-o", tmp_path / "fit"])
    assert code == 0, err
    return tmp_path / "fit.json"


def read_mesh(path):
    import trimesh

    return trimesh.load(path, process=False)


def test_fit_trim_writes_a_smaller_mesh_and_the_same_json(cup_file, tmp_path, capsys):
    path, points = cup_file
    common = ["fit", path, "--degree", "4", "--method", "3l", "--no-picture"]
    code, out, err = run(capsys, common + ["-o", tmp_path / "whole"])
    assert code == 0, err
    code, out, err = run(capsys, common + ["--trim", "-o", tmp_path / "trimmed"])
    assert code == 0, err
    line = [s for s in out.splitlines() if s.startswith("trimmed ")]
    assert len(line) == 1 and "% of the surface area farther than" in line[0], out
    whole, trimmed = read_mesh(tmp_path / "whole.ply"), read_mesh(tmp_path / "trimmed.ply")
    assert len(trimmed.faces) < len(whole.faces)
    distance = default_trim_distance(points)
    assert f"{distance:.4g}" in line[0]
    # within the trim distance, or in a hole between samples no farther than the gap distance
    assert cKDTree(points).query(np.asarray(trimmed.vertices))[0].max() <= default_gap_distance(points) * (1 + 1e-6)
    a = json.loads((tmp_path / "whole.json").read_text())
    b = json.loads((tmp_path / "trimmed.json").read_text())
    assert a["coefficients"] == b["coefficients"] and "trim" not in b
    # an explicit distance: at least as much is kept as with the smaller default
    code, out, err = run(capsys, common + ["--trim", "0.5", "-o", tmp_path / "wide"])
    assert code == 0, err
    assert "farther than 0.5 from the data" in out, out
    assert len(trimmed.faces) <= len(read_mesh(tmp_path / "wide.ply").faces) < len(whole.faces)


@pytest.mark.parametrize("value", ["-1", "abc", "0", "nan"])
def test_fit_refuses_a_bad_trim_distance(cup_file, tmp_path, capsys, value):
    path, _ = cup_file
    before = sorted(tmp_path.iterdir())
    code, out, err = run(capsys, ["fit", path, "--degree", "4", "--method", "3l", "--trim", value,
                                  "-o", tmp_path / "bad"])
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("ipfit fit: error: argument --trim:"), err
    assert "Traceback" not in err
    assert sorted(tmp_path.iterdir()) == before


def test_fit_refuses_trim_without_the_zero_set(cup_file, tmp_path, capsys):
    path, _ = cup_file
    code, out, err = run(capsys, ["fit", path, "--degree", "4", "--method", "3l", "--trim", "--no-zero-set",
                                  "-o", tmp_path / "x"])
    assert code == 2 and err.count("\n") == 1 and "--no-zero-set" in err, err
    assert not list(tmp_path.glob("x.*"))


HINT = "part of the zero set lies away from the data"


def _hints(out: str) -> list[str]:
    return [line for line in out.splitlines() if line.startswith(HINT)]


def test_fit_points_an_open_scan_at_trim(cup_file, tmp_path, capsys):
    # the fit closes the cup with a lid: its zero set reaches all the data but not all of it is
    # near the data, and the one line says so and which option takes the lid off
    path, _ = cup_file
    common = ["fit", path, "--degree", "4", "--method", "3l", "--no-picture"]
    code, out, err = run(capsys, common + ["-o", tmp_path / "whole"])
    assert code == 0, err
    (hint,) = _hints(out)
    precision, recall = (float(x) for x in re.search(r"precision ([0-9.]+) at recall ([0-9.]+)", hint).groups())
    assert recall >= 0.9 and recall - precision >= 0.1
    assert hint.endswith("--trim exports only the part near the data"), hint
    code, out, err = run(capsys, common + ["--trim", "-o", tmp_path / "trimmed"])
    assert code == 0 and not _hints(out), out  # asked for: the trimmed line instead
    # without the zero set the hint names the command that writes it trimmed, and that command works
    code, out, err = run(capsys, common + ["--no-zero-set", "-o", tmp_path / "json"])
    assert code == 0, err
    (hint,) = _hints(out)
    command = re.search(r"`ipfit (mesh .+ --trim)` writes only", hint).group(1).split()
    assert command[1] == str(tmp_path / "json.json")
    code, out, err = run(capsys, [*command, "-o", tmp_path / "from-hint.ply"])
    assert code == 0 and (tmp_path / "from-hint.ply").exists(), err


def test_fit_gives_no_trim_hint_for_a_closed_shape(tmp_path, capsys, rng):
    shape = synthetic.ellipsoid(1500, rng=rng)
    path = ipfit.write_points(tmp_path / "ellipsoid.ply", shape.points, shape.normals)
    code, out, err = run(capsys, ["fit", path, "--degree", "2", "--method", "3l", "--no-picture",
                                  "-o", tmp_path / "fit"])
    assert code == 0, err
    assert not _hints(out), out


def test_mesh_trim_uses_the_recorded_data_or_points(cup_file, tmp_path, capsys):
    path, points = cup_file
    result = fit_cup(capsys, path, tmp_path)
    code, out, err = run(capsys, ["mesh", result, "-o", tmp_path / "whole.ply"])
    assert code == 0, err
    code, out, err = run(capsys, ["mesh", result, "-o", tmp_path / "recorded.ply", "--trim"])
    assert code == 0, err
    assert out.splitlines()[-1].startswith("trimmed ") and "surface area" in out
    code, out, err = run(capsys, ["mesh", result, "-o", tmp_path / "given.ply", "--points", path, "--trim", "0.2"])
    assert code == 0, err
    assert "farther than 0.2 from" in out, out
    whole, recorded, given = (read_mesh(tmp_path / f"{n}.ply") for n in ("whole", "recorded", "given"))
    assert len(recorded.faces) < len(whole.faces) and len(given.faces) < len(whole.faces)
    assert cKDTree(points).query(np.asarray(given.vertices))[0].max() <= 0.2

    # without data to trim to: one clear line, nothing written
    moved = json.loads(result.read_text())
    moved["input"] = {"source": "gone.ply", "n_points": len(points), "normals": "file"}
    (tmp_path / "moved.json").write_text(json.dumps(moved))
    code, out, err = run(capsys, ["mesh", tmp_path / "moved.json", "-o", tmp_path / "none.ply", "--trim"])
    assert code == 2 and err.count("\n") == 1 and "--trim" in err and "--points DATA" in err, err
    # a distance that leaves nothing
    code, out, err = run(capsys, ["mesh", result, "-o", tmp_path / "none.ply", "--trim", "1e-9"])
    assert code == 2 and err.count("\n") == 1 and "larger distance" in err, err
    assert not (tmp_path / "none.ply").exists()


def test_mesh_trims_2d_curves(tmp_path, capsys):
    shape = synthetic.circle(400)
    path = tmp_path / "circle.json"
    shape.polynomial.save(path)
    right = shape.points[shape.points[:, 0] > 0]
    data = tmp_path / "right.csv"
    np.savetxt(data, right, delimiter=",", header="x,y", comments="")
    code, out, err = run(capsys, ["mesh", path, "-o", tmp_path / "c.csv", "--points", data, "--trim", "0.1"])
    assert code == 0, err
    assert "of the curve length farther than 0.1" in out, out
    rows = np.loadtxt(tmp_path / "c.csv", delimiter=",", comments="#", skiprows=3)
    assert cKDTree(right).query(rows[:, 1:])[0].max() <= 0.1
    assert Path(tmp_path / "c.csv").exists()


def test_the_figure_draws_the_trimmed_zero_set(fitted_cup):
    # plot_result(trim=...) draws what `ipfit fit --trim` leaves out lighter and see-through: the
    # same faces as without trim, some of them light (tests/test_figures_3d.py checks the colours)
    from matplotlib.collections import PolyCollection

    from ipfit.viz.plotting import TRIMMED_ALPHA, plot_result

    points, poly, _ = fitted_cup

    def drawn(fig):
        ax = fig.axes[0]
        return np.concatenate([c.get_facecolor() for c in ax.collections if isinstance(c, PolyCollection)])

    whole = drawn(plot_result(poly, points))
    trimmed_zs = ipfit.extract_zero_set(poly, points=points).trimmed(points)
    trimmed = drawn(plot_result(poly, points, trim=trimmed_zs.trim.distance))
    light = trimmed[:, 3] == TRIMMED_ALPHA
    assert len(trimmed) == len(whole) and 0 < light.sum() < len(whole) and not np.any(whole[:, 3] == TRIMMED_ALPHA)


def test_plot_trim_draws_less_of_the_closed_cup(cup_file, tmp_path, capsys):
    # `ipfit plot --trim` draws what `ipfit mesh --trim` exports: the lid the fit added is gone
    # (the inside wall shows through); the data comes from the result's recorded input.
    from matplotlib.image import imread

    path, points = cup_file
    result = fit_cup(capsys, path, tmp_path)
    code, out, err = run(capsys, ["plot", result, "-o", tmp_path / "whole.png"])
    assert code == 0, err
    code, out, err = run(capsys, ["plot", result, "-o", tmp_path / "trimmed.png", "--trim"])
    assert code == 0, err
    assert f"trimmed to within {default_trim_distance(points):.4g} of the data" in out, out

    whole, trimmed = (imread(tmp_path / name)[..., :3] for name in ("whole.png", "trimmed.png"))
    rows = np.flatnonzero((whole.min(axis=-1) < 0.95).any(axis=1)[40:]) + 40  # below the title
    middle = (rows.min() + rows.max()) // 2
    changed = np.abs(whole - trimmed).sum(axis=-1) > 0.1
    # the lid's pixels changed (the inside wall shows through), the wall and bottom did not
    assert changed.sum() > 1000
    assert changed[:middle].sum() > 0.95 * changed.sum()
    # refused in one line, nothing written
    code, out, err = run(capsys, ["plot", result, "-o", tmp_path / "bad.png", "--trim", "--no-points"])
    assert code == 2 and err.count("\n") == 1 and "--no-points" in err, err
    assert not (tmp_path / "bad.png").exists()


def test_the_viewer_draws_the_trimmed_zero_set(fitted_cup):
    # result_figure(trim=...) (ipfit view --trim, ipfit fit --html --trim): fewer triangles, the
    # kept ones near the data
    from ipfit.viz.viewer import result_figure

    points, poly, zs = fitted_cup
    distance = zs.trimmed(points).trim.distance

    def meshes(fig):
        return [t for t in fig.data if t.type == "mesh3d"]

    # no decimation, so that face counts compare
    whole = sum(len(t.i) for t in meshes(result_figure(poly, points, max_faces=10**7)))
    kept = meshes(result_figure(poly, points, trim=distance, max_faces=10**7))
    assert 0 < sum(len(t.i) for t in kept) < whole
    vertices = np.vstack([np.column_stack([t.x, t.y, t.z]) for t in kept])
    assert cKDTree(points).query(vertices)[0].max() <= default_gap_distance(points) * (1 + 1e-6)
    with pytest.raises(InvalidInputError, match="points"):
        result_figure(poly, None, trim=distance)


def test_view_trim_on_the_command_line(cup_file, tmp_path, capsys):
    path, points = cup_file
    result = fit_cup(capsys, path, tmp_path)
    code, out, err = run(capsys, ["view", result, "-o", tmp_path / "v.html", "--trim"])
    assert code == 0, err
    assert f"trimmed to within {default_trim_distance(points):.4g} of the data" in out, out
    code, out, err = run(capsys, ["view", result, "-o", tmp_path / "bad.html", "--trim", "--no-points"])
    assert code == 2 and err.count("\n") == 1 and "--no-points" in err, err
    assert not (tmp_path / "bad.html").exists()
    # ipfit fit --html --trim: the page's surfaces are the trimmed ones, every vertex near the data
    common = ["fit", path, "--degree", "4", "--method", "3l", "--no-picture", "--html"]
    assert run(capsys, common + ["-o", tmp_path / "whole"])[0] == 0
    assert run(capsys, common + ["--trim", "-o", tmp_path / "cut"])[0] == 0
    gap = default_gap_distance(points)  # kept: within the trim distance, or a hole no farther than this
    far = {name: cKDTree(points).query(page_vertices(tmp_path / f"{name}.html"))[0].max()
           for name in ("whole", "cut")}
    assert far["cut"] <= gap * (1 + 1e-5) < far["whole"]


def page_vertices(page) -> np.ndarray:
    """The vertices of every surface (mesh3d trace) a viewer page draws, read from its plotly data."""
    import base64

    text = Path(page).read_text(encoding="utf-8")
    start = text.index("Plotly.newPlot(")
    start = text.index("[", text.index(",", start))
    traces, _ = json.JSONDecoder().raw_decode(text, start)

    def values(v):
        if isinstance(v, dict):  # plotly's typed arrays: {"dtype": "f4", "bdata": base64}
            return np.frombuffer(base64.b64decode(v["bdata"]), dtype=np.dtype(v["dtype"]))
        return np.asarray(v, dtype=float)

    meshes = [t for t in traces if t.get("type") == "mesh3d"]
    assert meshes
    return np.vstack([np.column_stack([values(t[a]) for a in "xyz"]) for t in meshes]).astype(float)
