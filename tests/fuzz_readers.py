"""Fuzzing every reader: valid seed files of each format, mutated (truncations, bit flips,
inserted and deleted bytes, huge numbers, out-of-range indices), read by ``read_points``.

A read must end in one of two ways: a successful read (finite float64 points of shape (N, 2|3)
with N >= 3, normals None or of the same shape and unit length) or an
:class:`~ipfit.exceptions.IpfitError` with a one-line message. Anything else (another
exception, a numpy warning, a multi-line message) is a *foreign* outcome.

Two entry points share the seeds and the mutations:

- ``test_io_fuzz.py`` drives :func:`mutate` with hypothesis (shrinking finds minimal cases);
- :func:`fuzz_counts` runs a fixed number of seeded random mutations per format without
  hypothesis and returns the counts, for the robustness report::

      import sys; sys.path.insert(0, "tests")
      from fuzz_readers import fuzz_counts
      counts = fuzz_counts(examples=1000, seed=0)
      # {"ply-ascii": {"cases": 1000, "read": 412, "clean_error": 588, "foreign": 0, "foreign_examples": []}, ...}
"""

from __future__ import annotations

import random
import re
import struct
import tempfile
import warnings
from pathlib import Path

import numpy as np

from ipfit import io
from ipfit.exceptions import IpfitError, NormalsDroppedWarning

HUGE_TEXT = [b"1e308", b"-1.7976931348623157e308", b"1e-320", b"4e-308", b"2147483648", b"-1", b"99999999999999999999",
             b"1e999", b"0", b"-0", b"nan", b"inf"]
HUGE_BINARY = [struct.pack("<d", 1e308), struct.pack("<d", -1e308), struct.pack("<d", 5e-324),
               struct.pack("<f", 3e38), struct.pack("<i", 2**31 - 1), struct.pack("<i", -1), struct.pack("<I", 10**9),
               struct.pack("<Q", 2**63 - 1), b"\xff\xff\xff\xff", b"\x00\x00\x00\x00"]
_NUMBER = re.compile(rb"-?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?")


# -- seeds: one small valid file per format -------------------------------------------------------

def _sphere(n: int = 40, seed: int = 0):
    rng = np.random.default_rng(seed)
    normals = rng.normal(size=(n, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return normals * 2.0 + [1.0, -2.0, 0.5], normals


def make_seeds(folder: Path) -> dict[str, Path]:
    """Write one small valid file per format into ``folder``; returns {format label: path}."""
    import trimesh
    from PIL import Image

    from scanner_files import e57_file, las_file, pcd_file

    folder = Path(folder)
    points, normals = _sphere()
    seeds: dict[str, Path] = {}

    def put(label: str, name: str) -> Path:
        seeds[label] = folder / name
        return seeds[label]

    io.write_points(put("ply-binary", "b.ply"), points, normals)
    io.write_points(put("ply-ascii", "a.ply"), points, normals, binary=False)
    io.write_points(put("csv", "p.csv"), points[:, :2], normals[:, :2])
    io.write_points(put("xyz", "p.xyz"), points, normals)
    io.write_points(put("npy", "p.npy"), points, normals)
    io.write_points(put("npz", "p.npz"), points, normals)
    ball = trimesh.creation.icosphere(subdivisions=1)
    ball.export(put("obj", "m.obj"))
    ball.export(put("off", "m.off"))
    ball.export(put("stl-binary", "b.stl"))
    put("stl-ascii", "a.stl").write_bytes(trimesh.exchange.stl.export_stl_ascii(ball).encode())
    put("ply-mesh", "m.ply").write_bytes(trimesh.exchange.ply.export_ply(ball, encoding="ascii"))
    put("glb", "m.glb").write_bytes(trimesh.Scene([ball, ball.copy().apply_translation([3, 0, 0])]).export(
        file_type="glb"))
    put("dae", "m.dae").write_bytes(trimesh.exchange.dae.export_collada([ball, ball.copy().apply_translation([3, 0, 0])]))
    put("3mf", "m.3mf").write_bytes(trimesh.Scene([ball, ball.copy().apply_translation([3, 0, 0])]).export(
        file_type="3mf"))
    yy, xx = np.mgrid[:24, :24]
    disc = ((xx - 12) ** 2 + (yy - 11) ** 2 < 60).astype(np.uint8) * 255
    Image.fromarray(disc).save(put("png", "s.png"))
    Image.fromarray(disc).save(put("gif", "s.gif"))
    world = points * 10 + [4.5e5, 5.2e6, 300.0]
    las_file(put("las", "s.las"), world, normals)
    las_file(put("laz", "s.laz"), world, normals)
    pcd_file(put("pcd-ascii", "a.pcd"), world, normals, "ascii")
    pcd_file(put("pcd-binary", "b.pcd"), world, normals, "binary")
    e57_file(put("e57", "s.e57"), [(world, normals, None)])
    return seeds


# -- mutations ------------------------------------------------------------------------------------

MUTATIONS = ("truncate", "flip_bits", "insert", "delete", "huge_number", "huge_binary", "repeat")


def mutate(data: bytes, kind: str, r: random.Random, text: bool) -> bytes:
    """One mutation of ``data``; ``r`` decides where and what."""
    n = len(data)
    if kind == "truncate":
        return data[: r.randrange(n)]
    if kind == "flip_bits":
        out = bytearray(data)
        for _ in range(r.randint(1, 8)):
            out[r.randrange(n)] ^= 1 << r.randrange(8)
        return bytes(out)
    if kind == "insert":
        at = r.randrange(n + 1)
        return data[:at] + bytes(r.randrange(256) for _ in range(r.randint(1, 16))) + data[at:]
    if kind == "delete":
        at = r.randrange(n)
        return data[:at] + data[at + r.randint(1, 64):]
    if kind == "huge_number" and text:
        spans = [m.span() for m in _NUMBER.finditer(data)]
        if spans:
            out = data
            for start, end in sorted(r.sample(spans, min(len(spans), r.randint(1, 4))), reverse=True):
                out = out[:start] + r.choice(HUGE_TEXT) + out[end:]  # also counts and face indices
            return out
    if kind in ("huge_number", "huge_binary"):
        value = r.choice(HUGE_BINARY)
        at = r.randrange(max(1, n - len(value)))
        return data[:at] + value + data[at + len(value):]
    if kind == "repeat":
        start = r.randrange(n)
        return data[:start] + data[start:start + r.randint(1, 200)] * r.randint(2, 5) + data[start:]
    raise ValueError(kind)


def is_text(data: bytes) -> bool:
    return b"\x00" not in data[:2000] and all(b < 128 for b in data[:200])


# -- the oracle -----------------------------------------------------------------------------------

def read_outcome(path: Path) -> tuple[str, str]:
    """("read" | "clean_error" | "foreign", detail) for one file."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # a numpy warning escaping is foreign
            warnings.simplefilter("ignore", NormalsDroppedWarning)  # ours, on purpose
            cloud = io.read_points(path)
    except IpfitError as exc:
        message = str(exc)
        if "\n" in message or not message.startswith(str(path)):
            return "foreign", f"badly formed message: {message!r}"
        return "clean_error", message
    except Exception as exc:  # noqa: BLE001 - counting exactly these is the point
        return "foreign", f"{type(exc).__name__}: {exc}"
    points, normals = cloud
    ok = (isinstance(points, np.ndarray) and points.dtype == np.float64 and points.ndim == 2
          and points.shape[1] in (2, 3) and len(points) >= 3 and np.isfinite(points).all())
    if ok and normals is not None:
        ok = (normals.shape == points.shape and np.isfinite(normals).all()
              and np.allclose(np.linalg.norm(normals, axis=1), 1.0))
    return ("read", "") if ok else ("foreign", f"bad arrays: points {getattr(points, 'shape', None)}")


def fuzz_counts(examples: int = 1000, seed: int = 0, formats=None, folder=None) -> dict[str, dict]:
    """Read ``examples`` mutated files per format; count successful reads, clean errors and
    foreign outcomes (with up to 5 examples of the latter)."""
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(folder or tmp)
        seeds = make_seeds(work)
        counts = {}
        for label, seed_path in seeds.items():
            if formats is not None and label not in formats:
                continue
            data = seed_path.read_bytes()
            text = is_text(data)
            r = random.Random(f"{seed}-{label}")
            tally = {"cases": 0, "read": 0, "clean_error": 0, "foreign": 0, "foreign_examples": []}
            target = work / f"fuzz_{label}{seed_path.suffix}"
            for _ in range(examples):
                target.write_bytes(mutate(data, r.choice(MUTATIONS), r, text))
                outcome, detail = read_outcome(target)
                tally["cases"] += 1
                tally[outcome] += 1
                if outcome == "foreign" and len(tally["foreign_examples"]) < 5:
                    tally["foreign_examples"].append(detail)
            counts[label] = tally
        return counts


if __name__ == "__main__":  # python tests/fuzz_readers.py [examples]
    import json
    import sys

    sys.path.insert(0, str(Path(__file__).parent))
    print(json.dumps(fuzz_counts(int(sys.argv[1]) if len(sys.argv) > 1 else 100), indent=1))
