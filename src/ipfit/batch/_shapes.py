"""One shape of a batch: its settings and generator, the inputs, and the fit a worker runs."""

from __future__ import annotations

import csv
import hashlib
import io
import json
import os
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from glob import glob, has_magic
from pathlib import Path
from typing import Any

import numpy as np

from .._utils.validation import check_int, error
from ..exceptions import InvalidInputError
from ..fitting.options import DEFAULT_DELTA, DEFAULT_EPSILON, DEFAULT_METHOD, DEFAULT_RULE, SearchOptions

#: The summary table's columns, in order (``seed``: the shape's own, :func:`shape_seed`).
COLUMNS = ("name", "input", "seed", "points", "dim", "selected_degree", "dissimilarity", "smoothness", "distance",
           "f_score", "n_spurious", "seconds", "status", "error")
GENERATED_PREFIX = "generated:"
#: The most shapes ``generated:N`` makes (they are made in memory before the batch starts).
MAX_GENERATED = 10_000
#: Names of the batch's own outputs (``summary.csv``, ``index.html``): no shape gets them.
RESERVED_NAMES = ("summary", "index")


def shape_seed(seed: int, name: str) -> int:
    """The seed shape ``name`` is fitted with in a batch of seed ``seed``: a whole number below 2**32.

    It depends on the batch seed and the shape's *name* only (not on its place in the queue
    or its worker), and it is an ordinary seed: ``ipfit fit FILE --seed THAT`` (or
    ``fit_adaptive(..., rng=THAT)``) with the batch's other options gives the shape's batch
    result. The batch writes it in ``summary.csv`` and in the result's ``batch.shape_seed``.

    >>> shape_seed(0, "heart") == shape_seed(0, "heart"), shape_seed(0, "heart") == shape_seed(0, "bunny")
    (True, False)
    >>> shape_seed(0, "heart") == shape_seed(1, "heart")
    False
    """
    text = f"{check_int(seed, 'seed', minimum=0)}:{name}"
    return int.from_bytes(hashlib.sha256(text.encode("utf-8")).digest()[:4], "little")


def shape_rng(seed: int, name: str) -> np.random.Generator:
    """The generator of shape ``name`` in a batch of seed ``seed``: ``default_rng(shape_seed(seed, name))``.

    >>> a, b = shape_rng(0, "heart").random(), shape_rng(0, "heart").random()
    >>> a == b, a == shape_rng(0, "bunny").random(), a == shape_rng(1, "heart").random()
    (True, False, False)
    """
    return np.random.default_rng(shape_seed(seed, name))


@dataclass(frozen=True)
class FitSettings:
    """The ``fit_adaptive`` settings of a batch, with the hash that marks its results."""

    method: Any = DEFAULT_METHOD
    options: SearchOptions | None = None
    min_degree: int = 2
    max_degree: int | None = None
    epsilon: float = DEFAULT_EPSILON
    delta: float = DEFAULT_DELTA
    rule: str = DEFAULT_RULE
    seed: int = 0
    outliers: str | float = "auto"

    def to_dict(self) -> dict:
        method = self.method if isinstance(self.method, str) else \
            f"{getattr(self.method, '__module__', '')}.{getattr(self.method, '__qualname__', repr(self.method))}"
        return {"method": method, "options": None if self.options is None else self.options.to_dict(),
                "min_degree": self.min_degree, "max_degree": self.max_degree, "epsilon": self.epsilon,
                "delta": self.delta, "rule": self.rule, "seed": self.seed, "outliers": self.outliers}

    @property
    def hash(self) -> str:
        from .. import __version__

        # "seeding": results of the earlier per-name generators (not ipfit fit's) are fitted again
        text = json.dumps({**self.to_dict(), "ipfit": __version__, "seeding": "shape_seed"}, sort_keys=True)
        return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]

    def fit(self, points, normals, name: str, faces=None):
        from ..degree.adaptive import fit_adaptive

        return fit_adaptive(points, normals, method=self.method, options=self.options, min_degree=self.min_degree,
                            max_degree=self.max_degree, epsilon=self.epsilon, delta=self.delta, rule=self.rule,
                            faces=faces, outliers=self.outliers, rng=shape_seed(self.seed, name))


@dataclass(frozen=True)
class _Task:
    name: str
    source: str  # a path, a bundled name, or "generated:N:SEED#i"
    data: tuple | None = None  # (points, normals) given in memory
    path: str | None = None  # the absolute path of a file input

    @property
    def identity(self) -> str:
        """What a finished result must record to be this shape's: the file, else the source."""
        return self.path or self.source


@dataclass(frozen=True)
class BatchResult:
    """What :func:`fit_many` returns: one row per shape (:data:`COLUMNS`) and the result JSONs by name.

    ``interrupted``: a signal (``signal``, SIGINT or SIGTERM) stopped the batch; the pending
    shapes' rows are ``cancelled``.
    """

    rows: tuple[dict, ...]
    results: Mapping[str, dict] = field(default_factory=dict)
    interrupted: bool = False
    seconds: float = 0.0
    signal: int | None = None

    def counts(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for row in self.rows:
            out[row["status"]] = out.get(row["status"], 0) + 1
        return out

    def to_csv(self) -> str:
        buffer = io.StringIO()
        writer = csv.DictWriter(buffer, COLUMNS, lineterminator="\n")
        writer.writeheader()
        writer.writerows({k: ("" if row.get(k) is None else row.get(k)) for k in COLUMNS} for row in self.rows)
        return buffer.getvalue()


# -- inputs ----------------------------------------------------------------------------------
def _point_files(folder: Path) -> list[Path]:
    from ..io import READ_FORMATS

    # is_file(): a FIFO or a device in the folder would block its reader forever
    return sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in READ_FORMATS)


def _file_task(path: Path, text: str | None = None) -> _Task:
    return _Task(path.stem, str(path) if text is None else text, path=str(path.resolve()))


def _generated(spec: str) -> list[_Task]:
    parts = spec[len(GENERATED_PREFIX):].split(":")
    try:
        n, seed = int(parts[0]), int(parts[1]) if len(parts) > 1 else 0
        if len(parts) > 2 or not 1 <= n <= MAX_GENERATED or seed < 0:
            raise ValueError
    except ValueError:
        raise InvalidInputError(f"{spec}: expected generated:N or generated:N:SEED (1 <= N <= {MAX_GENERATED:,}, "
                                "SEED >= 0). Fix the input.") from None
    from ..datasets.collection import collection

    return [_Task(s.name, f"{GENERATED_PREFIX}{n}:{seed}#{i}", (s.points, s.normals))
            for i, s in enumerate(collection(n, seed))]


def _given_name(name: Any) -> str:
    """A caller's shape name, refused unless it is a plain file name (it names ``OUTPUT/NAME.json``)."""
    text = str(name)
    if not text or text.startswith(".") or any(c in text for c in "/\\\0") or len(text.encode("utf-8")) > 200:
        raise error("inputs", "shape names that are plain file names (1 to 200 bytes, no '/' or '\\', not "
                    "starting with '.')", repr(text)[:60], "Rename the shape.")
    return text


def _path_task(text: str) -> list[_Task]:
    from ..datasets import bundled

    path = Path(text)
    if text.startswith(GENERATED_PREFIX):
        return _generated(text)
    if path.is_dir():
        return [_file_task(p) for p in _point_files(path)]
    if path.is_file():
        return [_file_task(path, text)]
    if path.exists():
        raise InvalidInputError(f"{text}: not a regular file (a FIFO, a device or a socket); reading it could "
                                "block forever. Pass a point file.")
    if has_magic(text):
        return [_file_task(Path(p), p) for p in sorted(glob(text)) if Path(p).is_file()]
    if text in bundled.dataset_names():
        return [_Task(text, text)]
    raise InvalidInputError(f"{text}: no such file or folder, nor a glob, a bundled dataset name or "
                            "generated:N. Check the input.")


def expand_inputs(inputs: Iterable[Any] | Mapping[str, Any]) -> list[_Task]:
    """Files, folders (their point files), globs, bundled names, ``generated:N[:SEED]`` (the
    :func:`~ipfit.datasets.collection`, ``N`` <= :data:`MAX_GENERATED`), ``{name: (points, normals)}``
    mappings or generated shapes -> one task per shape, named by :func:`unique_names`.

    A file reached twice (``in/`` and ``in/a.xyz``) is one shape; anything but a regular
    file (a FIFO, a device) is refused, or skipped inside a folder or a glob.
    """
    from ..datasets.collection import GeneratedShape

    tasks: list[_Task] = []
    items: list[tuple[str | None, Any]] = []  # (name or None, input)
    for item in [inputs] if isinstance(inputs, Mapping) else inputs:
        items += item.items() if isinstance(item, Mapping) else [(None, item)]
    for name, item in items:
        if name is not None:
            points, normals = item if isinstance(item, tuple) else (item, None)
            tasks.append(_Task(_given_name(name), _given_name(name), (np.asarray(points), normals)))
        elif isinstance(item, GeneratedShape):
            tasks.append(_Task(_given_name(item.name), item.name, (item.points, item.normals)))
        elif isinstance(item, (str, os.PathLike)):
            tasks += _path_task(os.fspath(item))
        else:
            raise error("inputs", "paths, names, GeneratedShape objects or a {name: (points, normals)} mapping",
                        type(item).__name__)
    if not tasks:
        raise InvalidInputError("inputs: no shapes found (empty folder or glob). Check the inputs.")
    # In-memory shapes are always distinct; a file or a named shape is read once.
    distinct = list({(t.identity if t.data is None or t.source.startswith(GENERATED_PREFIX) else id(t)): t
                     for t in tasks}.values())
    return unique_names(distinct)


def _digest(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:6]


def _clashing(tasks: list[_Task]) -> set[str]:
    """Names (case-folded: some file systems ignore case) shared by two shapes or reserved."""
    seen: dict[str, int] = {}
    for task in tasks:
        seen[task.name.casefold()] = seen.get(task.name.casefold(), 0) + 1
    return {n for n, count in seen.items() if count > 1} | set(RESERVED_NAMES)


def _renamed(task: _Task, name: str) -> _Task:
    return _Task(name, task.source, task.data, task.path)


def unique_names(tasks: list[_Task]) -> list[_Task]:
    """The shapes' names, unique and stable: each depends on the set of inputs, never on their order.

    A shape is named by its file's stem (``scans/a.ply`` -> ``a``; leading dots dropped), its
    dataset or generated name, or its key. Where two shapes share a name (ignoring case) or
    a name is reserved (:data:`RESERVED_NAMES`), a file shape takes its file name with the
    dots as dashes (``a.ply`` -> ``a-ply``, ``summary.csv`` -> ``summary-csv``); a name that
    still clashes gets ``-`` and 6 hex digits of its source's SHA-256 (``a-ply-3f2a9c``).

    >>> tasks = [_Task("a", "x/a.ply", path="/x/a.ply"), _Task("a", "x/a.xyz", path="/x/a.xyz"),
    ...          _Task("index", "index")]
    >>> [t.name for t in unique_names(tasks)] == [t.name for t in unique_names(tasks[::-1])][::-1]
    True
    >>> [t.name for t in unique_names(tasks)]
    ['a-ply', 'a-xyz', 'index-1bc04b']
    """
    tasks = [_renamed(t, t.name.lstrip(".") or "shape") if t.path else t for t in tasks]
    clash = _clashing(tasks)
    tasks = [_renamed(t, Path(t.path).name.lstrip(".").replace(".", "-"))
             if t.path and t.name.casefold() in clash else t for t in tasks]
    clash = _clashing(tasks)
    tasks = [_renamed(t, f"{t.name}-{_digest(t.identity)}") if t.name.casefold() in clash else t for t in tasks]
    clash = _clashing(tasks)
    for task in tasks:
        if task.name.casefold() in clash:
            other = next(t for t in tasks if t.name.casefold() == task.name.casefold() and t is not task)
            raise InvalidInputError(f"inputs: two shapes are both named {task.name!r} ({task.source} and "
                                    f"{other.source}). Give them different names.")
    return tasks


# -- one shape, on a worker ---------------------------------------------------------------------
def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


def _row(task: _Task, seed: int, **values) -> dict:
    return {**dict.fromkeys(COLUMNS), "name": task.name, "input": task.source, "seed": shape_seed(seed, task.name),
            **values}


def _row_of(task: _Task, seed: int, payload: Mapping, status: str) -> dict:
    measures, quality = payload.get("measures") or {}, payload.get("quality") or {}
    return _row(task, seed, points=payload.get("input", {}).get("n_points"), dim=payload.get("dim"),
                selected_degree=payload.get("selected_degree"), dissimilarity=measures.get("dissimilarity"),
                smoothness=measures.get("smoothness"), distance=measures.get("distance"),
                f_score=quality.get("f_score"), n_spurious=quality.get("n_spurious"),
                seconds=(payload.get("adaptive") or {}).get("seconds"), status=status)


def _fit_task(task: _Task, settings: FitSettings) -> dict:
    """Read and fit one shape; every error becomes a failed row (the worker lives on)."""
    start = time.perf_counter()
    try:
        if task.data is not None:
            points, normals, faces, path = task.data[0], task.data[1], None, None
        else:
            from ..datasets.loading import load

            data = load(task.source)
            points, normals, faces = data.points, data.normals, data.faces
            path = task.path
        with np.errstate(all="ignore"):
            result = settings.fit(points, normals, task.name, faces)
        points = np.asarray(points, dtype=float)
        payload = result.to_dict()
        payload["input"] = {"source": task.source, "n_points": len(points),
                            "normals": "estimated" if normals is None else "file"}
        if path is not None:
            payload["input"]["path"] = path
        payload["bounds"] = np.column_stack([points.min(axis=0), points.max(axis=0)]).tolist()
        payload["batch"] = {"settings_hash": settings.hash, "name": task.name, "seed": settings.seed,
                            "shape_seed": shape_seed(settings.seed, task.name)}
        return {"row": _row_of(task, settings.seed, payload, "ok"), "result": payload}
    except Exception as exc:  # noqa: BLE001 - isolate the shape: its row says what went wrong
        return {"row": _row(task, settings.seed, seconds=time.perf_counter() - start, status="failed",
                            error=_one_line(exc)), "result": None}
