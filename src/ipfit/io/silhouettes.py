"""Silhouette images: the outer boundary of the largest shape, as a 2D contour with normals.

:func:`trace_silhouette` works on an array of grey levels; :func:`read_image` is the reader
behind ``read_points("shape.png")`` (PNG, GIF, BMP, TIFF, JPEG... through Pillow).
"""

from __future__ import annotations

import io as _io
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validation import error
from ..exceptions import InvalidInputError, ReadError
from ..normals import contour_normals
from ._base import MIN_POINTS, Raw, short

__all__ = ["trace_silhouette", "read_image", "CONTOUR_SPAN", "IMAGE_SUFFIXES"]

#: Central-difference span for the normals of traced contours (see ``contour_normals``):
#: ±1 pixel only sees the 45° staircase of a traced boundary, ±2 averages it.
CONTOUR_SPAN = 2
IMAGE_SUFFIXES = (".png", ".gif", ".bmp", ".tif", ".tiff", ".jpg", ".jpeg", ".webp", ".pgm", ".pbm", ".ppm")


def trace_silhouette(image: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Outer boundary of the largest shape in an image, with outward normals.

    The foreground is the class (Otsu threshold; midway for two-level images) that is rarer
    on the image border; alpha is used instead of brightness when it varies. The image is
    padded with background so shapes touching the border close. Points are in pixel units,
    x to the right, y up (y = −row), at subpixel precision (marching squares).

    Raises
    ------
    InvalidInputError
        If no shape is found.
    """
    from skimage import measure

    img = np.asarray(image, dtype=np.float64)
    if img.ndim != 2 or min(img.shape) < 1:
        raise error("image", "a 2D array of grey levels", f"shape {img.shape}")
    lo, hi = float(img.min()), float(img.max())
    if not hi > lo:
        raise InvalidInputError("image: the image is uniform, no shape to trace. Use a silhouette "
                                "(a shape on a plain background).")
    img = (img - lo) / (hi - lo)
    levels = np.unique(img)
    if len(levels) == 2:
        level = 0.5
    else:
        from skimage.filters import threshold_otsu

        level = float(threshold_otsu(img))
    border = np.concatenate([img[0], img[-1], img[:, 0], img[:, -1]])
    if (border > level).mean() > 0.5:  # bright background: the shape is the dark part
        img, level = 1.0 - img, 1.0 - level
    padded = np.pad(img, 1, constant_values=0.0)
    contours = measure.find_contours(padded, level)
    best, best_area = None, 0.0
    for c in contours:
        if len(c) < MIN_POINTS + 1:
            continue
        r, q = c[:, 0], c[:, 1]
        area = 0.5 * abs(float(np.sum(q * np.roll(r, -1) - np.roll(q, -1) * r)))
        if area > best_area:
            best, best_area = c, area
    if best is None or best_area <= 0:
        raise InvalidInputError("image: no closed shape found. Use a silhouette (a shape on a plain background).")
    if np.array_equal(best[0], best[-1]):
        best = best[:-1]
    points = np.column_stack([best[:, 1] - 1.0, -(best[:, 0] - 1.0)])
    keep = np.ones(len(points), dtype=bool)  # marching squares can repeat a vertex at saddles
    keep[1:] = np.any(np.diff(points, axis=0) != 0, axis=1)
    points = points[keep]
    if len(points) < MIN_POINTS:
        raise InvalidInputError("image: the shape is too small to trace (fewer than 3 boundary points).")
    return points, contour_normals(points, span=min(CONTOUR_SPAN, (len(points) - 1) // 2))


def read_image(path: Path, raw: bytes) -> Raw:
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(_io.BytesIO(raw)) as im:
            im.load()
            if im.mode in ("RGBA", "LA", "PA") or (im.mode == "P" and "transparency" in im.info):
                alpha = np.asarray(im.convert("RGBA"))[:, :, 3]
                grey = alpha if alpha.min() != alpha.max() else np.asarray(im.convert("L"))
            else:
                grey = np.asarray(im.convert("L"))
    except UnidentifiedImageError:
        raise ReadError(f"{path}: not a readable image (Pillow does not recognise its content). "
                        "Check that the file is complete and of the format its extension says.") from None
    except (OSError, ValueError, SyntaxError, Image.DecompressionBombError) as exc:
        raise ReadError(f"{path}: not a readable image ({short(exc)}). "
                        "Check that the file is complete and of the format its extension says.") from None
    try:
        points, normals = trace_silhouette(grey)
    except InvalidInputError as exc:
        raise ReadError(f"{path}: {str(exc).removeprefix('image: ')}") from None
    return Raw(points, normals, normals_source="contour")
