"""One shape of a batch: its settings and generator, the inputs, and the fit a worker runs."""

from __future__ import annotations

import csv
import hashlib
import io
import json
import os
import time
from dataclasses import dataclass, field
from glob import glob, has_magic
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np

from .._validation import check_int, error
from ..exceptions import InvalidInputError
from ..options import DEFAULT_DELTA, DEFAULT_EPSILON, DEFAULT_METHOD, DEFAULT_RULE, SearchOptions

#: The summary table's columns, in order.
COLUMNS = ("name", "input", "points", "dim", "selected_degree", "dissimilarity", "smoothness", "distance", "f_score",
           "n_spurious", "seconds", "status", "error")
GENERATED_PREFIX = "generated:"


def shape_rng(seed: int, name: str) -> np.random.Generator:
    """The generator shape ``name`` is fitted with in a batch of seed ``seed``.

    >>> a, b = shape_rng(0, "heart").random(), shape_rng(0, "heart").random()
    >>> a == b, a == shape_rng(0, "bunny").random(), a == shape_rng(1, "heart").random()
    (True, False, False)
    """
    words = np.frombuffer(hashlib.sha256(name.encode("utf-8")).digest()[:16], dtype="<u4")
    return np.random.default_rng(np.random.SeedSequence([check_int(seed, "seed", minimum=0), *map(int, words)]))


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

    def to_dict(self) -> dict:
        method = self.method if isinstance(self.method, str) else \
            f"{getattr(self.method, '__module__', '')}.{getattr(self.method, '__qualname__', repr(self.method))}"
        return {"method": method, "options": None if self.options is None else self.options.to_dict(),
                "min_degree": self.min_degree, "max_degree": self.max_degree, "epsilon": self.epsilon,
                "delta": self.delta, "rule": self.rule, "seed": self.seed}

    @property
    def hash(self) -> str:
        from .. import __version__

        text = json.dumps({**self.to_dict(), "ipfit": __version__}, sort_keys=True)
        return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]

    def fit(self, points, normals, name: str, faces=None):
        from ..adaptive import fit_adaptive

        return fit_adaptive(points, normals, method=self.method, options=self.options, min_degree=self.min_degree,
                            max_degree=self.max_degree, epsilon=self.epsilon, delta=self.delta, rule=self.rule,
                            faces=faces, rng=shape_rng(self.seed, name))


@dataclass(frozen=True)
class _Task:
    name: str
    source: str  # a path, a bundled name, or "generated:N:SEED#i"
    data: tuple | None = None  # (points, normals) given in memory


@dataclass(frozen=True)
class BatchResult:
    """What :func:`fit_many` returns: one row per shape (:data:`COLUMNS`) and the result JSONs by name."""

    rows: tuple[dict, ...]
    results: Mapping[str, dict] = field(default_factory=dict)
    interrupted: bool = False
    seconds: float = 0.0

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

    return sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in READ_FORMATS)


def _generated(spec: str) -> list[_Task]:
    parts = spec[len(GENERATED_PREFIX):].split(":")
    try:
        n, seed = int(parts[0]), int(parts[1]) if len(parts) > 1 else 0
        if len(parts) > 2 or n < 1 or seed < 0:
            raise ValueError
    except ValueError:
        raise InvalidInputError(f"{spec}: expected generated:N or generated:N:SEED (N >= 1, SEED >= 0). "
                                "Fix the input.") from None
    from ..datasets.collection import collection

    return [_Task(s.name, f"{GENERATED_PREFIX}{n}:{seed}#{i}", (s.points, s.normals))
            for i, s in enumerate(collection(n, seed))]


def expand_inputs(inputs: Iterable[Any] | Mapping[str, Any]) -> list[_Task]:
    """Files, folders (their point files), globs, bundled names, ``generated:N[:SEED]`` (the
    :func:`~ipfit.datasets.collection`), ``{name: (points, normals)}`` mappings or generated shapes ->
    one task per shape, with unique names (a repeated file stem gets ``-2``, ``-3``, ...)."""
    from ..datasets import bundled
    from ..datasets.collection import GeneratedShape

    tasks: list[_Task] = []
    items = []
    for item in [inputs] if isinstance(inputs, Mapping) else inputs:
        items += item.items() if isinstance(item, Mapping) else [(None, item)]
    for name, item in items:
        if name is not None:
            points, normals = item if isinstance(item, tuple) else (item, None)
            tasks.append(_Task(str(name), str(name), (np.asarray(points), normals)))
        elif isinstance(item, GeneratedShape):
            tasks.append(_Task(item.name, item.name, (item.points, item.normals)))
        elif isinstance(item, (str, os.PathLike)):
            text = os.fspath(item)
            path = Path(text)
            if text.startswith(GENERATED_PREFIX):
                tasks += _generated(text)
            elif path.is_dir():
                tasks += [_Task(p.stem, str(p)) for p in _point_files(path)]
            elif path.exists():
                tasks.append(_Task(path.stem, text))
            elif has_magic(text):
                tasks += [_Task(Path(p).stem, p) for p in sorted(glob(text)) if Path(p).is_file()]
            elif text in bundled.dataset_names():
                tasks.append(_Task(text, text))
            else:
                raise InvalidInputError(f"{text}: no such file or folder, nor a glob, a bundled dataset name or "
                                        "generated:N. Check the input.")
        else:
            raise error("inputs", "paths, names, GeneratedShape objects or a {name: (points, normals)} mapping",
                        type(item).__name__)
    if not tasks:
        raise InvalidInputError("inputs: no shapes found (empty folder or glob). Check the inputs.")
    seen: dict[str, int] = {}
    unique = []
    for task in tasks:
        count = seen[task.name] = seen.get(task.name, 0) + 1
        unique.append(task if count == 1 else _Task(f"{task.name}-{count}", task.source, task.data))
    return unique


# -- one shape, on a worker ---------------------------------------------------------------------
def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


def _row(task: _Task, **values) -> dict:
    return {**dict.fromkeys(COLUMNS), "name": task.name, "input": task.source, **values}


def _row_of(task: _Task, payload: Mapping, status: str) -> dict:
    measures, quality = payload.get("measures") or {}, payload.get("quality") or {}
    return _row(task, points=payload.get("input", {}).get("n_points"), dim=payload.get("dim"),
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
            from ..cli._common import load_input

            data = load_input(task.source)
            points, normals, faces = data.points, data.normals, data.faces
            path = str(Path(task.source).resolve()) if Path(task.source).exists() else None
        with np.errstate(all="ignore"):
            result = settings.fit(points, normals, task.name, faces)
        points = np.asarray(points, dtype=float)
        payload = result.to_dict()
        payload["input"] = {"source": task.source, "n_points": int(len(points)),
                            "normals": "estimated" if normals is None else "file"}
        if path is not None:
            payload["input"]["path"] = path
        payload["bounds"] = np.column_stack([points.min(axis=0), points.max(axis=0)]).tolist()
        payload["batch"] = {"settings_hash": settings.hash, "name": task.name, "seed": settings.seed}
        return {"row": _row_of(task, payload, "ok"), "result": payload}
    except Exception as exc:  # noqa: BLE001 - isolate the shape: its row says what went wrong
        return {"row": _row(task, seconds=time.perf_counter() - start, status="failed", error=_one_line(exc)),
                "result": None}
