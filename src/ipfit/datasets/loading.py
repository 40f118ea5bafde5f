"""The one public loader: a point file or a bundled dataset's name, as a :class:`~ipfit.Cloud`.

The command line, :func:`ipfit.fit_many` and the experiment scripts all read their data
here, so that one spec (``bunny``, ``scan.ply``) gives the same points, normals, faces and
subsample everywhere. It prints nothing: how many points the source held and how many were
kept are the cloud's ``n_file`` and ``len(cloud)``, for the caller to report.

>>> cloud = load("Boot", max_points=500)
>>> cloud.name, len(cloud), cloud.n_file, cloud.normals_source, cloud.faces is None
('boot', 500, 1354, 'contour', True)
"""

from __future__ import annotations

import os

import numpy as np

from .._utils.foreign import ForeignParts, foreign_parts
from .._utils.validation import as_points, check_int, check_rng
from ..cloud import Cloud
from ..exceptions import ReadError
from ..io._base import MIN_POINTS, as_path
from ..io.readers import read_points_faces
from . import bundled

__all__ = ["load"]


def load(spec: str | os.PathLike | object, *, max_points: int | None = None, rng=0,
         largest_outline: bool = False) -> Cloud:
    """Read a point file, or a bundled dataset by name, or take another library's geometry.

    Parameters
    ----------
    spec : str, path or geometry object
        A path to any file :func:`ipfit.read_points` reads, or (a str naming no existing
        file) the name of a bundled dataset, in any case (``ipfit.dataset_names()``). A file
        of that name wins over the dataset. Or a ``trimesh.Trimesh``/``PointCloud``, an Open3D
        ``PointCloud``/``TriangleMesh``, a PyVista ``PolyData`` or a pandas DataFrame: its
        points, and its normals and faces when it has them (:mod:`ipfit._utils.foreign`), as
        they are (duplicates not merged, normals not estimated).
    max_points : int, optional
        Keep at most this many points, drawn at random without replacement (order kept).
        A subsample has no faces: they indexed the points before the draw.
    rng : int, Generator or None
        Seed of that draw; the default 0 gives the same subset on every run (the subset
        ``ipfit fit --max-points`` fits).
    largest_outline : bool
        A silhouette image: the outline of its largest shape alone, without its holes
        (``ipfit fit --largest-outline``).

    Returns
    -------
    Cloud
        Its points (read-only), unit normals or None, faces or None, ``name`` (the file's
        stem, the dataset's name), ``source`` (the :class:`~pathlib.Path` given, or the
        dataset's name), ``n_file`` (points before subsampling) and ``normals_source``.

    Raises
    ------
    ReadError
        The file cannot be read (see :func:`ipfit.read_points`), or ``spec`` is neither an
        existing path nor a dataset name (one line, with the nearest name when there is one).
    InvalidInputError
        ``max_points`` is not an integer >= 3, or ``rng`` is not a seed.
    """
    parts = foreign_parts(spec, "spec")
    if parts is not None:
        return _from_object(parts, max_points, rng)
    path = as_path(spec, "spec")
    if max_points is not None:
        max_points = check_int(max_points, "max_points", minimum=MIN_POINTS)
    generator = check_rng(rng)
    # A PathLike is always a path: only a str can name a dataset.
    if path.exists() or not isinstance(spec, str):
        cloud, faces = read_points_faces(path, max_points=max_points, rng=generator, largest_outline=largest_outline)
        return Cloud(cloud.points, cloud.normals, faces, name=path.stem, source=path, n_file=cloud.n_file,
                     normals_source=cloud.normals_source)
    name = bundled.resolve_name(spec)
    if name is None:
        names = ", ".join(bundled.dataset_names())
        raise ReadError(f"{spec}: no such file, nor a bundled dataset name ({names}).{bundled.suggestion(spec)} "
                        "Check the path.")
    points, normals = dataset = bundled.load_dataset(name)
    faces = bundled.dataset_faces(name)
    points, normals, faces = _drawn(points, normals, faces, max_points, generator)
    return Cloud(points, normals, faces, name=name, source=name, n_file=len(dataset.points),
                 normals_source=dataset.normals_source)


def _from_object(parts: ForeignParts, max_points: int | None, rng) -> Cloud:
    """A Cloud of a foreign object's arrays as they are (a file's normals are not normalised
    either), subsampled as a file's would be."""
    points = as_points(parts.points)
    normals = None if parts.normals is None else as_points(parts.normals, "normals")
    faces = parts.faces
    if max_points is not None:
        max_points = check_int(max_points, "max_points", minimum=MIN_POINTS)
    generator = check_rng(rng)
    n_file = len(points)
    points, normals, faces = _drawn(points, normals, faces, max_points, generator)
    return Cloud(points, normals, faces, name=parts.kind.split(".")[-1], source=parts.kind, n_file=n_file)


def _drawn(points, normals, faces, max_points: int | None, generator):
    """At most ``max_points`` points, drawn as ipfit.read_points draws from a file (no faces after)."""
    if max_points is None or len(points) <= max_points:
        return points, normals, faces
    keep = np.sort(generator.choice(len(points), max_points, replace=False))
    return points[keep], None if normals is None else normals[keep], None
