"""How many points ``outliers="auto"`` leaves out of clean shapes (issue 30: clean data unchanged).

    python experiments/outlier_flags.py [--shapes DIR_OR_NAME ...] [--fit]

Scores every clean development shape (the bundled datasets, ../shared/data/mpeg7-dev and
../shared/data/turk-dev, read as corrupt.py reads them: contour rows, mesh vertices) with
:func:`ipfit.score_outliers` and prints how many have any point marked as an outlier. A shape with
none is fitted by ``fit_adaptive(points)`` exactly as with ``outliers="none"``. ``--fit`` fits
each shape that has some (seed 0, both ways) and scores both fits against the clean shape as
``experiments/robust.py`` does (F-score at 2% of the box diagonal; a mesh's faces, a contour's
segments).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
DEFAULT = ["boot", "airplane", "butterfly", "apple", "duck", "bunny",
           str(SHARED / "mpeg7-dev"), str(SHARED / "turk-dev")]


def clouds(entries):
    import ipfit

    for entry in entries:
        path = Path(entry)
        if not path.exists():
            cloud = ipfit.load(entry)
            yield entry, cloud.points, cloud.faces
            continue
        for file in sorted(path.iterdir()) if path.is_dir() else [path]:
            if file.suffix == ".csv":
                rows = [line.split(",")[:2] for line in file.read_text().splitlines()
                        if line.strip() and not line.startswith(("#", "x"))]
                yield file.name, np.array(rows, float), None
            elif file.suffix in (".ply", ".obj", ".off", ".stl"):
                import trimesh

                mesh = trimesh.load(file, force="mesh", process=True)
                yield file.name, np.asarray(mesh.vertices, float), np.asarray(mesh.faces)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shapes", nargs="+", default=DEFAULT)
    parser.add_argument("--fit", action="store_true", help="fit the shapes with outliers both ways and score them")
    args = parser.parse_args(argv)
    from ipfit import fit_adaptive, quality, score_outliers

    rows = [(name, points, faces, score_outliers(points).count) for name, points, faces in clouds(args.shapes)]
    flagged = [row for row in rows if row[3]]
    print(f"{len(rows)} clean shapes; {len(flagged)} with any point treated as an outlier by outliers='auto'")
    for name, points, faces, count in flagged:
        line = f"  {name}: {count} of {len(points)} points ({count / len(points):.1%})"
        if args.fit:
            scores = []
            for mode in ("none", "auto"):
                poly = fit_adaptive(points, rng=0, outliers=mode).polynomial
                q = quality(poly, points, faces=faces, ordered_contour=faces is None and points.shape[1] == 2)
                scores.append(f"{mode}: F {q.f_score:.3f}, {q.n_spurious} spurious")
            line += "; fitted bare, " + " / ".join(scores)
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
