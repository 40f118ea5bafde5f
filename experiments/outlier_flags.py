"""How many points ``outliers="auto"`` leaves out of clean shapes (issue 30: clean data unchanged).

    python experiments/outlier_flags.py [--shapes DIR_OR_NAME ...]

Scores every clean development shape (the bundled datasets, ../shared/data/mpeg7-dev and
../shared/data/turk-dev, read as corrupt.py reads them: contour rows, mesh vertices) with
:func:`ipfit.score_outliers` and prints how many have any point marked as an outlier. A shape with
none is fitted by ``fit_adaptive(points)`` exactly as with ``outliers="none"``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
DEFAULT = ["boot", "airplane", "butterfly", "apple", "duck", "bunny", str(SHARED / "mpeg7-dev"), str(SHARED / "turk-dev")]


def clouds(entries):
    import ipfit

    for entry in entries:
        path = Path(entry)
        if not path.exists():
            yield entry, ipfit.load(entry).points
            continue
        for file in sorted(path.iterdir()) if path.is_dir() else [path]:
            if file.suffix == ".csv":
                rows = [line.split(",")[:2] for line in file.read_text().splitlines()
                        if line.strip() and not line.startswith(("#", "x"))]
                yield file.name, np.array(rows, float)
            elif file.suffix in (".ply", ".obj", ".off", ".stl"):
                import trimesh

                yield file.name, np.asarray(trimesh.load(file, force="mesh", process=True).vertices, float)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shapes", nargs="+", default=DEFAULT)
    args = parser.parse_args(argv)
    from ipfit import score_outliers

    rows = [(name, len(points), score_outliers(points).count) for name, points in clouds(args.shapes)]
    flagged = [row for row in rows if row[2]]
    print(f"{len(rows)} clean shapes; {len(flagged)} with any point treated as an outlier by outliers='auto'")
    for name, n, count in flagged:
        print(f"  {name}: {count} of {n} points ({count / n:.1%})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
