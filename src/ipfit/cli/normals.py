"""``ipfit normals INPUT -o OUT.ply``: the file's normals, or estimated ones, written for inspection."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from ._common import Outputs, nonnegative_float, positive_int
from ._progress import Progress, progress_mode

NAME = "normals"
HELP = "write a point file's normals (or estimated ones) to a PLY/OBJ/OFF/CSV/XYZ/NPY file"
DESCRIPTION = """\
Read INPUT (a point file: PLY, OBJ, OFF, STL, XYZ/TXT/CSV, NPY/NPZ, or a silhouette image; or the
name of a bundled dataset, see `ipfit datasets`) and write its points with normals to OUT (format
by extension: .ply, .obj, .off, .csv, .xyz, .txt, .npy, .npz), e.g. to look at them in MeshLab or CloudCompare.

The normals are the file's own (for meshes without vertex normals: area-weighted from the faces;
for images: outward normals of the traced boundary). With --normals estimate (as in `ipfit fit`),
or when the file has none, they are estimated by
k-nearest-neighbour PCA with consistent outward orientation; where the file has normals too, the
command reports how many estimated normals point the opposite way to the file's and how many differ
from them by more than 30°. For meshes, --outward first checks which of those reference normals
point out of the mesh's solid (generalized winding numbers; a mesh that passes through itself, or
has holes, has some that do not) and reports the disagreement over the others too. --noise gives
the estimate the noise's σ (a number in the points' units, or auto: the outlier score's estimate, as
`ipfit fit` finds it): noisy 3D points then get the normals of an even sample of them whose k nearest
reach about 4 σ (or, too sparse for that, neighbourhoods grown to 4 σ where no size looks flatter).
"""

_OFF_LINE = 30.0  # degrees: report estimated normals whose line differs more than this


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", metavar="INPUT", help="point file or bundled dataset name")
    parser.add_argument("-o", "--output", metavar="OUT", required=True,
                        help="output file: .ply (default binary), .obj, .off, .csv, .xyz, .txt, .npy or .npz")
    parser.add_argument("--normals", choices=("file", "estimate"), default=None,
                        help="copy the file's normals or estimate them and compare them with the file's "
                             "(default: the file's when present), as in `ipfit fit`")
    parser.add_argument("--k", type=positive_int, metavar="K",
                        help="neighbours per point for the estimate (default 6 in 2D, 12 in 3D)")
    parser.add_argument("--noise", type=noise_setting, metavar="auto|SIGMA",
                        help="the noise's σ for the estimate, in the points' units, or auto: the outlier score's "
                             "estimate (default: none, the sizes from the points alone)")
    parser.add_argument("--outward", action="store_true",
                        help="with --normals estimate on a mesh: also compare only where the reference normals "
                             "point out of the solid (winding numbers: seconds per 10,000 vertices × 10,000 faces)")
    parser.add_argument("--ascii", action="store_true", help="write an ASCII PLY instead of a binary one")


def noise_setting(text: str) -> str | float:
    """--noise: 'auto', or σ >= 0 checked as the other non-negative flags are."""
    if text == "auto":
        return text
    try:
        return nonnegative_float(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"expected auto or a number >= 0 (the noise's σ), got {text!r}") from None


# How the normals' origin (Cloud.normals_source) is named in the report.
_SOURCES = {"file": "the file", "contour": "the traced boundary", "faces": "the faces (area-weighted)"}


def _load(spec: str):
    """(points, reference normals or None, where they come from, label, faces or None)."""
    from ..datasets.loading import load

    cloud = load(spec)
    if not isinstance(cloud.source, Path):
        return cloud.points, cloud.normals, f"the bundled '{cloud.name}' reference", cloud.name, cloud.faces
    source = None if cloud.normals_source is None else _SOURCES.get(cloud.normals_source)
    return cloud.points, cloud.normals, source, str(cloud.source), cloud.faces


def run(args: argparse.Namespace) -> int:
    from .. import io
    from ..exceptions import InvalidInputError
    from ..normals import DEFAULT_K, estimate_normals, normal_agreement

    out = Path(args.output)
    outputs = Outputs([out], inputs=[args.input], suffixes=tuple(io.WRITE_FORMATS))
    points, reference, source, label, faces = _load(args.input)
    n, dim = points.shape
    has = f"normals from {source}" if reference is not None else "without normals"
    print(f"{label}: {n:,} points ({dim}D), {has}")

    if args.normals == "file" and reference is None:
        raise InvalidInputError(f"--normals file: {label} has no normals. Use --normals estimate.")
    estimate = args.normals == "estimate"
    normals = reference
    if estimate or reference is None:
        k = args.k if args.k is not None else DEFAULT_K[dim]
        start = time.perf_counter()
        noise = args.noise
        if noise == "auto":
            from ..robust import score_outliers

            noise = score_outliers(points).noise_scale
            print(f"noise σ = {noise:.4g} (the outlier score's estimate)")
        normals = estimate_normals(points, k=k, noise=noise, progress=Progress(progress_mode(False), stream=sys.stdout))
        seconds = time.perf_counter() - start
        why = "" if estimate else " (the input has none)"
        print(f"estimated normals{why} from the {k} nearest points of each point (k = {k}) in {seconds:.2f} s")
        if reference is not None:
            _report_agreement(normal_agreement(normals, reference), source)
    elif args.k is not None or args.noise is not None:
        unused = [name for name, value in (("--k", args.k), ("--noise", args.noise)) if value is not None]
        said = "was not used: it sets" if len(unused) == 1 else "were not used: they set"
        print(f"note: {' and '.join(unused)} {said} the estimate's neighbourhood, and the file's normals were "
              "copied (add --normals estimate to estimate them)")
    if args.outward:
        if estimate and reference is not None and faces is not None and dim == 3:
            _report_outward(points, faces, reference, normals, source)
        else:
            print("note: --outward was not used: it only applies with --normals estimate on a 3D mesh (with faces) "
                  "that has reference normals")
    with outputs.writing() as stage:
        io.write_points(stage(out), points, normals, binary=not args.ascii)
    print(f"wrote {out} ({n:,} points with normals)")
    return 0


def _share(count: int, total: int) -> str:
    return f"{count:,} of {total:,} ({100 * count / max(total, 1):.2f}%)"


def _report_agreement(agreement, source: str) -> None:
    n = agreement.compared
    flipped = int(agreement.flipped.sum())
    off = int((agreement.angles > _OFF_LINE).sum())
    print(f"{_share(flipped, n)} estimated normals point the opposite way to those from {source}")
    print(f"{_share(off, n)} estimated normals differ from those from {source} by more than {_OFF_LINE:.0f}° "
          f"(as lines, whichever way they point); median difference {agreement.median_angle:.2f}°")


def _report_outward(points, faces, reference, estimated, source) -> None:
    import numpy as np

    from ..geometry.mesh import outward_vertices

    start = time.perf_counter()
    outward = outward_vertices(points, faces, reference)  # False where the reference is NaN
    seconds = time.perf_counter() - start
    n, kept = len(points), int(outward.sum())
    flipped = int((outward & (np.einsum("ij,ij->i", estimated, reference) < 0)).sum())
    if kept == n:
        print(f"all {n:,} normals from {source} point out of the mesh's solid (winding numbers, {seconds:.1f} s)")
    else:
        print(f"{n - kept:,} of {n:,} normals from {source} do not point out of the mesh's solid: it passes through "
              f"itself or is open there (winding numbers, {seconds:.1f} s)")
    print(f"where they do point out, {_share(flipped, kept)} estimated normals point the opposite way")
