"""Small scanner and scene files written with the same libraries ipfit reads them with:
multi-mesh GLB and 3MF, LAS/LAZ with offsets and scales, PCD (ASCII, binary, compressed), E57 with
surface normals and scan poses. Used by test_io_scanners.py and as seeds by fuzz_readers.py."""

from __future__ import annotations

import uuid
from pathlib import Path

import numpy as np

E57_NOR = ("nor", "http://www.libe57.org/E57_NOR_surface_normals.txt")


def unit(v):
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def glb_scene(path: Path, file_type: str = "glb"):
    """A GLB (or 3MF) with three meshes under moved, rotated and scaled nodes; returns the scene."""
    import trimesh
    from trimesh import transformations as tf

    scene = trimesh.Scene()
    box = trimesh.creation.box(extents=[1.0, 2.0, 3.0])
    scene.add_geometry(box, geom_name="box", node_name="moved_box", transform=tf.translation_matrix([5.0, 0.0, -1.0]))
    scene.add_geometry(trimesh.creation.icosphere(subdivisions=1), geom_name="ball", node_name="turned_ball",
                       transform=tf.concatenate_matrices(tf.translation_matrix([0.0, 3.0, 0.0]),
                                                         tf.rotation_matrix(0.7, [1.0, 1.0, 0.0]),
                                                         tf.scale_matrix(2.0)))
    scene.add_geometry(trimesh.creation.cylinder(radius=0.5, height=1.0, sections=12), geom_name="can",
                       node_name="can", transform=tf.rotation_matrix(np.pi / 2, [0.0, 0.0, 1.0]))
    options = {"include_normals": True} if file_type == "glb" else {}
    Path(path).write_bytes(scene.export(file_type=file_type, **options))
    return scene


def las_file(path: Path, xyz: np.ndarray, normals: np.ndarray | None = None, *,
             offsets=(4.5e5, 5.2e6, 300.0), scales=(1e-3, 1e-3, 1e-3)) -> np.ndarray:
    """Write LAS/LAZ (by suffix); returns the coordinates as stored (rounded to the scales)."""
    import laspy

    header = laspy.LasHeader(point_format=3, version="1.4")
    header.offsets, header.scales = np.asarray(offsets), np.asarray(scales)
    if normals is not None:
        header.add_extra_dims([laspy.ExtraBytesParams(name=n, type=np.float64) for n in ("nx", "ny", "nz")])
    las = laspy.LasData(header)
    las.x, las.y, las.z = xyz.T
    if normals is not None:
        las.nx, las.ny, las.nz = normals.T
    las.write(str(path))
    return np.round((xyz - header.offsets) / header.scales) * header.scales + header.offsets


def pcd_file(path: Path, xyz: np.ndarray, normals: np.ndarray | None, encoding: str) -> None:
    import pypcd4

    fields = ("x", "y", "z") + (() if normals is None else ("normal_x", "normal_y", "normal_z"))
    table = xyz if normals is None else np.hstack([xyz, normals])
    cloud = pypcd4.PointCloud.from_points(table, fields, (np.float64,) * len(fields))
    cloud.save(str(path), encoding=pypcd4.Encoding(encoding))


def e57_file(path: Path, scans) -> None:
    """Scans of (xyz, normals or None, pose or None), pose = (quaternion w x y z, translation),
    stored as doubles (pye57's own writer stores single precision and no normals)."""
    import pye57
    from pye57 import libe57

    with pye57.E57(str(path), mode="w") as e57:
        image = e57.image_file
        image.extensionsAdd(*E57_NOR)
        for xyz, normals, pose in scans:
            scan = libe57.StructureNode(image)
            scan.set("guid", libe57.StringNode(image, "{%s}" % uuid.uuid4()))
            if pose is not None:
                pose_node, rotation, translation = (libe57.StructureNode(image) for _ in range(3))
                for key, value in zip("wxyz", pose[0]):
                    rotation.set(key, libe57.FloatNode(image, float(value)))
                for key, value in zip("xyz", pose[1]):
                    translation.set(key, libe57.FloatNode(image, float(value)))
                pose_node.set("rotation", rotation)
                pose_node.set("translation", translation)
                scan.set("pose", pose_node)
            columns = {"cartesianX": xyz[:, 0], "cartesianY": xyz[:, 1], "cartesianZ": xyz[:, 2]}
            if normals is not None:
                columns.update({"nor:normalX": normals[:, 0], "nor:normalY": normals[:, 1],
                                "nor:normalZ": normals[:, 2]})
            prototype = libe57.StructureNode(image)
            for name in columns:
                prototype.set(name, libe57.FloatNode(image, 0.0, libe57.E57_DOUBLE))
            points = libe57.CompressedVectorNode(image, prototype, libe57.VectorNode(image, True))
            scan.set("points", points)
            e57.data3d.append(scan)
            arrays = {name: np.ascontiguousarray(col, dtype=np.float64) for name, col in columns.items()}
            buffers = libe57.VectorSourceDestBuffer()
            for name, array in arrays.items():
                buffers.append(libe57.SourceDestBuffer(image, name, array, len(array), True, True))
            writer = points.writer(buffers)
            writer.write(len(xyz))
            writer.close()
