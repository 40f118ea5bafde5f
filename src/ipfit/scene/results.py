"""A scene's result: one :class:`~ipfit.AdaptiveResult` per object, the segmentation, and its JSON.

The JSON (``docs/result-format.md``, "Scenes") is an ipfit result whose ``objects`` lists one
complete result per object, each readable alone by :func:`ipfit.load_result` (with its own
``bounds``, ``bounding_box`` ``[[min...], [max...]]`` and ``n_points``), whose ``planes`` lists the
removed planes and whose ``segmentation`` records how the scan was split (the label of every
point among them). :func:`load_scene` reads it back as a :class:`SceneView`.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._result_schema import FORMAT_NAME, FORMAT_VERSION
from ..degree.adaptive import AdaptiveResult
from ..degree.results import ResultView, load_result, result_view
from ..exceptions import InvalidInputError, ReadError
from ..polynomial import ImplicitPolynomial
from .segment import Segmentation

__all__ = ["SceneResult", "SceneView", "load_scene", "is_scene", "object_box"]


def object_box(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """``[[min...], [max...]]`` of ``points``: an object's ``bounding_box``."""
    return np.vstack([points.min(axis=0), points.max(axis=0)])


@dataclass(frozen=True, eq=False)
class SceneResult:
    """Result of :func:`ipfit.fit_scene`: a list of per-object fits with the segmentation.

    It behaves as the sequence of its objects' :class:`~ipfit.AdaptiveResult` (``len``,
    indexing, iteration), each with its own degree, quality and reasons.

    Attributes
    ----------
    objects : one :class:`~ipfit.AdaptiveResult` per object, in the order of
        ``segmentation.objects`` (largest first).
    segmentation : the :class:`~ipfit.scene.segment.Segmentation` (labels per point, planes, clutter).
    boxes : each object's ``[[min...], [max...]]`` in the input's coordinates.
    planes : the removed planes as degree-1 polynomials when ``keep_planes`` was asked, else empty.
    dim, n_points : the scan's dimension and number of points.
    nit, nfev : iterations and objective evaluations over every object.
    success : every object's fit succeeded.
    message : what was found, in words (objects, touching ones, planes, clutter, outliers).
    seconds : wall-clock time of the whole scene.
    """

    objects: tuple[AdaptiveResult, ...]
    segmentation: Segmentation
    boxes: tuple[NDArray[np.float64], ...]
    dim: int
    n_points: int
    nit: int
    nfev: int
    success: bool
    message: str
    seconds: float
    planes: tuple[ImplicitPolynomial, ...] = ()

    def __len__(self) -> int:
        return len(self.objects)

    def __getitem__(self, index: int) -> AdaptiveResult:
        return self.objects[index]

    def __iter__(self) -> Iterator[AdaptiveResult]:
        return iter(self.objects)

    @property
    def touching(self) -> tuple[int, ...]:
        """The objects that may be two touching objects (fitted as one)."""
        return tuple(i for i, c in enumerate(self.segmentation.objects) if c.touching)

    def to_dict(self, source: str = "points", path: str | None = None, normals: str = "estimated") -> dict:
        """The scene JSON (see the module notes); ``source``, ``path`` and ``normals`` fill ``input``."""
        seg = self.segmentation
        objects = []
        for i, (result, cluster, box) in enumerate(zip(self.objects, seg.objects, self.boxes, strict=True)):
            entry = result.to_dict()
            entry["input"] = {"source": f"{source}#object-{i}", "n_points": cluster.n_points, "normals": normals}
            entry["bounds"] = box.T.tolist()
            entry["bounding_box"] = box.tolist()
            entry["n_points"] = cluster.n_points
            entry["touching"] = cluster.touching
            if cluster.note:
                entry["note"] = cluster.note
            objects.append(entry)
        planes = []
        for i, plane in enumerate(seg.planes):
            record = plane.to_dict()
            if i < len(self.planes):
                record["polynomial"] = self.planes[i].to_dict()
            planes.append(record)
        record_input: dict[str, Any] = {"source": source, "n_points": self.n_points, "normals": normals}
        if path is not None:
            record_input["path"] = path
        boxes = np.array(self.boxes) if self.boxes else None
        out: dict[str, Any] = {
            "format": FORMAT_NAME, "version": FORMAT_VERSION, "dim": self.dim, "objects": objects, "planes": planes,
            "segmentation": {**seg.to_dict(), "success": self.success, "message": self.message,
                             "seconds": self.seconds},
            "input": record_input}
        if boxes is not None:
            out["bounds"] = np.column_stack([boxes[:, 0].min(axis=0), boxes[:, 1].max(axis=0)]).tolist()
        return out


def is_scene(data: Any) -> bool:
    """Whether a result's JSON object (a dict) is a scene: it lists ``objects``."""
    return isinstance(data, Mapping) and "objects" in data


@dataclass(frozen=True)
class SceneView:
    """A scene result read back: the JSON, each object as a :class:`~ipfit.degree.results.ResultView`.

    Attributes
    ----------
    data : the validated JSON object.
    source : the file's path, or "result".
    objects : one view per object (``view.polynomial`` its final polynomial, ``view.bounds`` its box).
    planes : the ``planes`` records (normal, offset, n_points, and the degree-1 ``polynomial`` when kept).
    """

    data: Mapping[str, Any]
    source: str
    objects: tuple[ResultView, ...]
    planes: tuple[Mapping[str, Any], ...]

    @property
    def dim(self) -> int:
        return self.objects[0].dim if self.objects else int(self.data.get("dim") or 3)

    @property
    def input(self) -> Mapping[str, Any]:
        return self.data.get("input") or {}

    @property
    def segmentation(self) -> Mapping[str, Any]:
        return self.data.get("segmentation") or {}

    @property
    def labels(self) -> NDArray[np.int64] | None:
        """Each input point's object (or -1), when the scene records them."""
        labels = self.segmentation.get("labels")
        return None if labels is None else np.asarray(labels, dtype=np.int64)

    def plane_polynomials(self) -> list[ImplicitPolynomial]:
        return [ImplicitPolynomial.from_dict(p["polynomial"], f"{self.source}: planes[{i}].polynomial")
                for i, p in enumerate(self.planes) if isinstance(p.get("polynomial"), Mapping)]

    def __len__(self) -> int:
        return len(self.objects)


def load_scene(result: Any, source: str | None = None) -> SceneView:
    """Read a scene result (a path, JSON text, a dict or a :class:`SceneResult`) into a :class:`SceneView`.

    Raises
    ------
    ReadError, InvalidInputError
        Not a valid result (one line naming the bad key), or a result of one shape, not a scene.
    """
    if isinstance(result, SceneView):
        return result
    if isinstance(result, SceneResult):
        result = result.to_dict()
    is_path = isinstance(result, os.PathLike) or (isinstance(result, str) and not result.lstrip().startswith("{"))
    source = source or (str(result) if is_path else "result")
    data = load_result(result, source)
    if not is_scene(data):
        kind = ReadError if is_path else InvalidInputError
        raise kind(f"{source}: a result of one shape, not a scene (it has no \"objects\"). Read it with "
                   "ipfit.load_result, or fit the scan with ipfit fit --objects.")
    objects = tuple(result_view(entry, f"{source}: objects[{i}]") for i, entry in enumerate(data["objects"]))
    return SceneView(data, source, objects, tuple(data.get("planes") or ()))
