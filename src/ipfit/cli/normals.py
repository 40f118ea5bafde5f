"""``ipfit normals INPUT -o OUT.ply``: the file's normals, or estimated ones, written for inspection."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from ._common import Outputs, positive_int

NAME = "normals"
HELP = "write a point file's normals (or estimated ones) to a PLY/OBJ/OFF/CSV/XYZ/NPY file"
DESCRIPTION = """\
Read INPUT (a point file: PLY, OBJ, OFF, STL, XYZ/TXT/CSV, NPY/NPZ, or a silhouette image; or the
name of a bundled dataset, see `ipfit datasets`) and write its points with normals to OUT (format
by extension: .ply, .obj, .off, .csv, .xyz, .txt, .npy, .npz), e.g. to look at them in MeshLab or CloudCompare.

The normals are the file's own (for meshes without vertex normals: area-weighted from the faces;
for images: outward normals of the traced boundary). With --estimate, or when the file has none,
they are estimated by k-nearest-neighbour PCA with consistent outward orientation; where the file
has normals too, the command reports how many estimated normals point the other way. For meshes,
--outward first checks which of those reference normals point out of the mesh's solid (generalized
winding numbers; a mesh that passes through itself, or has holes, has some that do not) and
reports the disagreement over the others too.
"""

_OFF_LINE = 30.0  # degrees: report estimated normals whose line differs more than this


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", metavar="INPUT", help="point file or bundled dataset name")
    parser.add_argument("-o", "--output", metavar="OUT", required=True,
                        help="output file: .ply (default binary), .obj, .off, .csv, .xyz, .txt, .npy or .npz")
    parser.add_argument("--estimate", action="store_true",
                        help="estimate the normals (and compare them with the file's) instead of copying them")
    parser.add_argument("--k", type=positive_int, metavar="K",
                        help="neighbours per point for the estimate (default 6 in 2D, 12 in 3D)")
    parser.add_argument("--outward", action="store_true",
                        help="with --estimate on a mesh: also compare only where the reference normals point out "
                             "of the solid (winding numbers: seconds per 10,000 vertices × 10,000 faces)")
    parser.add_argument("--ascii", action="store_true", help="write an ASCII PLY instead of a binary one")


def _load(spec: str):
    """(points, reference normals or None, where they come from, label, faces or None)."""
    from .. import io
    from ..datasets import bundled
    from ..exceptions import ReadError

    path = Path(spec)
    if not path.exists() and spec in bundled.dataset_names():
        points, normals = bundled.load_dataset(spec)
        return points, normals, f"the bundled '{spec}' reference", spec, bundled.dataset_faces(spec)
    if path.exists() or path.suffix:  # a path: the reader reports a missing file clearly
        mesh = io.read_mesh(path)
        if mesh.normals is not None:
            traced = path.suffix.lower() in io._IMAGE_SUFFIXES
            return mesh.points, mesh.normals, "the traced boundary" if traced else "the file", str(path), mesh.faces
        if mesh.faces is not None and mesh.points.shape[1] == 3:
            normals = io._complete(mesh.points, io.vertex_normals_from_faces(mesh.points, mesh.faces))
            return mesh.points, normals, "the faces (area-weighted)", str(path), mesh.faces
        return mesh.points, None, None, str(path), mesh.faces
    names = ", ".join(bundled.dataset_names())
    raise ReadError(f"{spec}: no such file, nor a bundled dataset name ({names}). Check the path.")


def run(args: argparse.Namespace) -> int:
    from .. import io
    from ..exceptions import InvalidInputError
    from ..normals import DEFAULT_K, estimate_normals, normal_agreement

    out = Path(args.output)
    outputs = Outputs([out], inputs=[args.input], suffixes=tuple(io.WRITE_FORMATS))
    points, reference, source, label, faces = _load(args.input)
    n, dim = points.shape
    print(f"{label}: {n:,} points ({dim}D), " + (f"normals from {source}" if reference is not None else "no normals"))

    normals = reference
    if args.estimate or reference is None:
        k = args.k if args.k is not None else DEFAULT_K[dim]
        start = time.perf_counter()
        normals = estimate_normals(points, k=k)
        seconds = time.perf_counter() - start
        why = "" if args.estimate else " (the input has none)"
        print(f"estimated normals{why}: k = {k}, {seconds:.2f} s")
        if reference is not None:
            agreement = normal_agreement(normals, reference)
            flipped = int(agreement.flipped.sum())
            off = int((agreement.angles > _OFF_LINE).sum())
            print(f"disagree with {source}: {flipped:,} of {agreement.compared:,} point the other way "
                  f"({100 * flipped / max(agreement.compared, 1):.2f}%); {off:,} lines off by more than "
                  f"{_OFF_LINE:.0f}°; median angle {agreement.median_angle:.2f}°")
    elif args.k is not None:
        print("note: --k only matters with --estimate")
    if args.outward:
        if args.estimate and reference is not None and faces is not None and dim == 3:
            _report_outward(points, faces, reference, normals, source)
        else:
            print("note: --outward only matters with --estimate on a 3D mesh (faces) that has reference normals")
    with outputs.writing() as stage:
        io.write_points(stage(out), points, normals, binary=not args.ascii)
    print(f"wrote {out} ({n:,} points with normals)")
    return 0


def _report_outward(points, faces, reference, estimated, source) -> None:
    import numpy as np

    from ..solid import outward_vertices

    start = time.perf_counter()
    outward = outward_vertices(points, faces, reference)  # False where the reference is NaN
    seconds = time.perf_counter() - start
    kept = int(outward.sum())
    flipped = int((outward & (np.einsum("ij,ij->i", estimated, reference) < 0)).sum())
    print(f"{len(points) - kept:,} of {len(points):,} normals from {source} do not point out of the mesh's solid "
          f"(it passes through itself or is open there; {seconds:.1f} s); over the other {kept:,}, "
          f"{flipped:,} estimated normals point the other way ({100 * flipped / max(kept, 1):.2f}%)")
