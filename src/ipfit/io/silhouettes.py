"""Silhouette images: the boundaries of the largest shape, as a 2D contour with normals.

:func:`trace_silhouette` works on an array of grey levels; :func:`read_image` is the reader
behind ``read_points("shape.png")`` (PNG, GIF, BMP, TIFF, JPEG... through Pillow). The shape
is read whole: its outline and the outlines of its holes (an "&" has two), as one ordered
contour of several loops, one after the other (:func:`chain_loops`), with outward normals of
the solid; ``largest_outline=True`` keeps the outline alone, as before.
"""

from __future__ import annotations

import io as _io
import math
import warnings
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._utils.validation import error
from ..exceptions import InvalidInputError, ReadError
from ..normals import contour_normals
from ._base import MIN_POINTS, Raw, chain_loops, chain_offsets, short

__all__ = ["trace_silhouette", "trace_silhouettes", "read_silhouettes", "read_image", "check_image_pixels",
           "chain_loops", "CONTOUR_SPAN", "IMAGE_SUFFIXES",
           "MAX_IMAGE_PIXELS", "MIN_SHAPE_POINTS"]

#: Central-difference span for the normals of traced contours (see ``contour_normals``):
#: ±1 pixel only sees the 45° staircase of a traced boundary, ±2 averages it.
CONTOUR_SPAN = 2
#: Largest image traced, in pixels (width × height). Tracing needs about 18 bytes per pixel
#: (a padded float64 copy, and find_contours' own copy): 50 million pixels peak near 1 GB. The
#: size is checked from the file's header, before anything is decoded.
MAX_IMAGE_PIXELS = 50_000_000
#: Fewest boundary points of a traced shape: a smaller outline is a speck (a disc of radius
#: 3 pixels has about 20), too small to tell a curve by, and the fit's outlier scoring needs
#: 12 distinct points.
MIN_SHAPE_POINTS = 20
_USE_A_SILHOUETTE = ("Use a silhouette: one shape clearly darker or brighter than a plain background, "
                     "or opaque on a transparent one.")
IMAGE_SUFFIXES = (".png", ".gif", ".bmp", ".tif", ".tiff", ".jpg", ".jpeg", ".webp", ".pgm", ".pbm", ".ppm")


def check_image_pixels(width: int, height: int) -> None:
    """Refuse an image of more than :data:`MAX_IMAGE_PIXELS` pixels, suggesting a size that fits."""
    pixels = width * height
    if pixels > MAX_IMAGE_PIXELS:
        shrink = math.sqrt(MAX_IMAGE_PIXELS / pixels)
        raise error("image", f"at most {MAX_IMAGE_PIXELS:,} pixels", f"{width} x {height} = {pixels:,}",
                    f"Downscale it (e.g. to {max(1, int(width * shrink))} x {max(1, int(height * shrink))}).")


def _signed_area(c: NDArray) -> float:
    r, q = c[:, 0], c[:, 1]
    return 0.5 * float(np.sum(q * np.roll(r, -1) - np.roll(q, -1) * r))


def _as_xy(c: NDArray) -> NDArray[np.float64]:
    """Marching-squares rows and columns of the padded image → x right, y up; the repeated
    last point and repeated vertices (at saddles) dropped."""
    if np.array_equal(c[0], c[-1]):
        c = c[:-1]
    points = np.column_stack([c[:, 1] - 1.0, -(c[:, 0] - 1.0)])
    keep = np.ones(len(points), dtype=bool)
    keep[1:] = np.any(np.diff(points, axis=0) != 0, axis=1)
    return points[keep]


def _holes(contours: list[NDArray], best: NDArray, best_area: float) -> list[NDArray]:
    """The outlines of the holes of the shape outlined by ``best``: the contours inside it wound
    the other way (holes, not islands) and inside no other contour inside it (an island in a
    hole is another shape, and so are its holes)."""
    from skimage.measure import points_in_poly

    inside = [c for c in contours if c is not best and len(c) >= MIN_SHAPE_POINTS + 1
              and points_in_poly(c[:1], best)[0]]
    sign = math.copysign(1.0, best_area)
    out = []
    for c in inside:
        if math.copysign(1.0, _signed_area(c)) == sign:
            continue  # an island's outline
        if any(points_in_poly(c[:1], other)[0] for other in inside if other is not c):
            continue  # inside another outline inside the shape: the hole of an island
        out.append(c)
    return out


def trace_silhouette(image: ArrayLike, *, largest_outline: bool = False) -> tuple[NDArray[np.float64],
                                                                                   NDArray[np.float64]]:
    """Boundaries of the largest shape in an image (its outline, then its holes), with the
    outward normals of the shape.

    The foreground is the class (Otsu threshold; midway for two-level images) that is rarer
    on the image border. The image is padded with background so shapes touching the border
    close. Points are in pixel units, x to the right, y up (y = −row), at subpixel precision
    (marching squares). :func:`read_image` chooses the channel: alpha when it separates a
    shape from a transparent background, otherwise luminance.

    The outline runs counter-clockwise; each hole (of at least :data:`MIN_SHAPE_POINTS`
    boundary points) follows it, clockwise, chained by :func:`chain_loops`. With
    ``largest_outline`` the outline alone (holes dropped).

    Raises
    ------
    InvalidInputError
        If the image holds no shape (uniform, or only specks of fewer than
        :data:`MIN_SHAPE_POINTS` boundary points), or has more than :data:`MAX_IMAGE_PIXELS` pixels.
    """
    from skimage import measure

    img = np.asarray(image)
    if img.ndim != 2 or min(img.shape) < 1 or img.dtype.kind not in "biuf":
        raise error("image", "a 2D array of grey levels", f"shape {img.shape} and dtype {img.dtype}")
    check_image_pixels(img.shape[1], img.shape[0])
    # One float64 buffer, already padded with background, changed in place: with the copy
    # find_contours makes, the peak stays near 18 bytes per pixel (MAX_IMAGE_PIXELS).
    padded = np.zeros((img.shape[0] + 2, img.shape[1] + 2))
    inner = padded[1:-1, 1:-1]
    inner[...] = img
    del img
    lo, hi = float(inner.min()), float(inner.max())
    if not hi > lo:
        raise InvalidInputError(f"image: the image is uniform, no shape to trace. {_USE_A_SILHOUETTE}")
    inner -= lo
    inner /= hi - lo
    if np.all((inner == 0.0) | (inner == 1.0)):  # two levels, now exactly 0 and 1
        level = 0.5
    else:
        from skimage.filters import threshold_otsu

        level = float(threshold_otsu(inner))
    border = np.concatenate([inner[0], inner[-1], inner[:, 0], inner[:, -1]])
    if (border > level).mean() > 0.5:  # bright background: the shape is the dark part
        np.subtract(1.0, inner, out=inner)
        level = 1.0 - level
    contours = measure.find_contours(padded, level)
    best, best_area = None, 0.0
    for c in contours:
        if len(c) < MIN_POINTS + 1:
            continue
        area = _signed_area(c)
        if abs(area) > abs(best_area):
            best, best_area = c, area
    if best is None or best_area == 0:
        raise InvalidInputError(f"image: no closed shape in the image. {_USE_A_SILHOUETTE}")
    points = _as_xy(best)
    if len(points) < MIN_SHAPE_POINTS:
        column, row = points.mean(axis=0) * [1, -1]
        raise InvalidInputError(
            f"image: no shape in the image, only specks: the largest covers {abs(best_area):.3g} pixels "
            f"near column {column:.0f}, row {row:.0f} (an outline needs at least {MIN_SHAPE_POINTS} "
            f"boundary points). {_USE_A_SILHOUETTE}")
    holes = [] if largest_outline else [_as_xy(c) for c in _holes(contours, best, best_area)]
    loops = [_oriented(points, 1.0)] + [_oriented(h, -1.0) for h in holes if len(h) >= MIN_SHAPE_POINTS]
    normals = []
    for i, loop in enumerate(loops):
        outward = contour_normals(loop, span=min(CONTOUR_SPAN, (len(loop) - 1) // 2))
        normals.append(outward if i == 0 else -outward)  # a hole's solid is outside its loop
    offsets = chain_offsets(loops)
    return (np.concatenate([np.roll(loop, -k, axis=0) for loop, k in zip(loops, offsets, strict=True)]),
            np.concatenate([np.roll(n, -k, axis=0) for n, k in zip(normals, offsets, strict=True)]))


def _oriented(loop: NDArray, sign: float) -> NDArray[np.float64]:
    """``loop`` (x right, y up) counter-clockwise (``sign`` 1) or clockwise (−1)."""
    x, y = loop[:, 0], loop[:, 1]
    area = float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    return loop if area * sign >= 0 else loop[::-1].copy()


def read_image(path: Path, raw: bytes, *, largest_outline: bool = False) -> Raw:
    """An image's largest shape, its outline and holes (:func:`trace_silhouette`)."""
    from PIL import Image, UnidentifiedImageError

    try:
        with _open_image(raw) as im:
            check_image_pixels(*im.size)  # from the header: nothing is decoded yet
            im.load()
            grey = _grey_levels(im)
        points, normals = trace_silhouette(grey, largest_outline=largest_outline)
    except UnidentifiedImageError:
        raise ReadError(f"{path}: not a readable image (Pillow does not recognise its content). "
                        "Check that the file is complete and of the format its extension says.") from None
    except Image.DecompressionBombError:  # Pillow's own limit, raised before the size is known
        # Pillow raises it only while its limit is set: MAX_IMAGE_PIXELS is an int here, not None
        raise ReadError(f"{path}: expected at most {MAX_IMAGE_PIXELS:,} pixels, got more than "
                        f"{2 * Image.MAX_IMAGE_PIXELS:,}. Downscale the image.") from None  # type: ignore[operator]
    except (OSError, ValueError, SyntaxError) as exc:
        if isinstance(exc, InvalidInputError):  # ours: the size, or no shape to trace
            raise ReadError(f"{path}: {str(exc).removeprefix('image: ')}") from None
        raise ReadError(f"{path}: not a readable image ({short(exc)}). "
                        "Check that the file is complete and of the format its extension says.") from None
    return Raw(points, normals, normals_source="contour")


def _open_image(raw: bytes):
    from PIL import Image

    with warnings.catch_warnings():  # Pillow's warning of large images: MAX_IMAGE_PIXELS is lower
        warnings.simplefilter("ignore", Image.DecompressionBombWarning)
        return Image.open(_io.BytesIO(raw))


def _grey_levels(im) -> NDArray:
    """The channel that carries the shape: alpha when it separates one, else luminance.

    Alpha carries a shape when the image's background is transparent: most of the border
    below the level that splits alpha in two. An opaque image with a few transparent pixels
    (scikit-image's ``horse.png`` has 12, its rounded corners) draws its shape in colour, so
    it is traced from its luminance, composited over white as a viewer shows it.
    Single-channel images of more than 8 bits (16-bit PNG or TIFF, integer or float TIFF)
    keep their full depth: converting them to 8 bits would clip every level above 255.
    """
    from PIL import Image

    if im.mode in ("RGBA", "LA", "PA", "RGBa", "La") or (im.mode == "P" and "transparency" in im.info):
        rgba = im.convert("RGBA")
        alpha = np.asarray(rgba.getchannel("A"))
        if _alpha_carries_shape(alpha):
            return alpha
        white = Image.new("RGBA", rgba.size, (255, 255, 255, 255))
        return np.asarray(Image.alpha_composite(white, rgba).convert("L"))
    if im.mode in ("I", "F") or im.mode.startswith("I;16"):
        return np.asarray(im)
    return np.asarray(im.convert("L"))


def _alpha_carries_shape(alpha: NDArray) -> bool:
    """Whether alpha separates a shape: it varies, and most of the image's border is transparent."""
    lo, hi = int(alpha.min()), int(alpha.max())
    if lo == hi:
        return False
    border = np.concatenate([alpha[0], alpha[-1], alpha[:, 0], alpha[:, -1]])
    return bool(np.mean(border < (lo + hi) / 2) > 0.5)


# -- every silhouette of an image (ipfit fit --objects, ipfit.fit_scene) ------------------------
def trace_silhouettes(image: ArrayLike) -> list[tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """The outer boundary of every separate shape in an image, largest first, with outward normals.

    The foreground is found as :func:`trace_silhouette` finds it (Otsu, the class rarer on the
    border); its pieces are told apart by ``skimage.measure.label`` (8-connected), and each is
    traced alone, at subpixel precision, in the grey levels around it. Shapes of fewer than
    :data:`MIN_SHAPE_POINTS` boundary points are specks, left out. Coordinates as
    :func:`trace_silhouette`'s (pixels, x to the right, y up).

    Raises
    ------
    InvalidInputError
        If the image holds no shape.
    """
    from skimage import measure
    from skimage.morphology import dilation

    img = np.asarray(image)
    if img.ndim != 2 or min(img.shape) < 1 or img.dtype.kind not in "biuf":
        raise error("image", "a 2D array of grey levels", f"shape {img.shape} and dtype {img.dtype}")
    check_image_pixels(img.shape[1], img.shape[0])
    grey = np.zeros((img.shape[0] + 2, img.shape[1] + 2))
    grey[1:-1, 1:-1] = img
    lo, hi = float(img.min()), float(img.max())
    if not hi > lo:
        raise InvalidInputError(f"image: the image is uniform, no shape to trace. {_USE_A_SILHOUETTE}")
    inner = grey[1:-1, 1:-1]
    inner -= lo
    inner /= hi - lo
    if np.all((inner == 0.0) | (inner == 1.0)):
        level = 0.5
    else:
        from skimage.filters import threshold_otsu

        level = float(threshold_otsu(inner))
    border = np.concatenate([inner[0], inner[-1], inner[:, 0], inner[:, -1]])
    if (border > level).mean() > 0.5:
        np.subtract(1.0, inner, out=inner)
        level = 1.0 - level
    grey[0], grey[-1], grey[:, 0], grey[:, -1] = 0.0, 0.0, 0.0, 0.0
    labels = measure.label(grey > level, connectivity=2)
    shapes = []
    for region in measure.regionprops(labels):
        r0, c0, r1, c1 = region.bbox
        r0, c0, r1, c1 = max(r0 - 2, 0), max(c0 - 2, 0), min(r1 + 2, grey.shape[0]), min(c1 + 2, grey.shape[1])
        # this shape's grey levels and one ring of pixels round it; every other shape is background
        near = dilation(labels[r0:r1, c0:c1] == region.label, np.ones((3, 3), dtype=bool))
        window = np.where(near, grey[r0:r1, c0:c1], 0.0)
        best, best_area = None, 0.0
        for c in measure.find_contours(window, level):
            if len(c) < MIN_POINTS + 1:
                continue
            area = 0.5 * abs(float(np.sum(c[:, 1] * np.roll(c[:, 0], -1) - np.roll(c[:, 1], -1) * c[:, 0])))
            if area > best_area:
                best, best_area = c, area
        if best is None:
            continue
        if np.array_equal(best[0], best[-1]):
            best = best[:-1]
        points = np.column_stack([best[:, 1] + c0 - 1.0, -(best[:, 0] + r0 - 1.0)])
        keep = np.ones(len(points), dtype=bool)
        keep[1:] = np.any(np.diff(points, axis=0) != 0, axis=1)
        points = points[keep]
        if len(points) >= MIN_SHAPE_POINTS:
            shapes.append((best_area, points))
    if not shapes:
        raise InvalidInputError(f"image: no shape in the image. {_USE_A_SILHOUETTE}")
    shapes.sort(key=lambda s: -s[0])
    return [(p, contour_normals(p, span=min(CONTOUR_SPAN, (len(p) - 1) // 2))) for _, p in shapes]


def read_silhouettes(path: str | Path) -> list[tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """Every separate silhouette of an image file (:func:`trace_silhouettes`), read as
    :func:`read_image` reads one; errors are :class:`~ipfit.ReadError` naming the file."""
    from PIL import Image, UnidentifiedImageError

    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ReadError(f"{path}: cannot be read ({short(exc)}). Check the path.") from None
    try:
        with _open_image(raw) as im:
            check_image_pixels(*im.size)
            im.load()
            grey = _grey_levels(im)
        return trace_silhouettes(grey)
    except UnidentifiedImageError:
        raise ReadError(f"{path}: not a readable image (Pillow does not recognise its content). "
                        "Check that the file is complete and of the format its extension says.") from None
    except Image.DecompressionBombError:
        raise ReadError(f"{path}: expected at most {MAX_IMAGE_PIXELS:,} pixels. Downscale the image.") from None
    except (OSError, ValueError, SyntaxError) as exc:
        if isinstance(exc, InvalidInputError):
            raise ReadError(f"{path}: {str(exc).removeprefix('image: ')}") from None
        raise ReadError(f"{path}: not a readable image ({short(exc)}). "
                        "Check that the file is complete and of the format its extension says.") from None
