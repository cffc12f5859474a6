"""rgbd-toolkit from Python: capture folders, views and meshes as numpy arrays, and every stage
of the method with the tools' options and defaults (docs/python.md).

    import rgbd_toolkit as rt
    mesh = rt.reconstruct("cap/")            # = rgbd-reconstruct cap/ -o mesh.ply
    mesh.vertices, mesh.faces, mesh.colors   # N x 3 float64, M x 3 int64, N x 3 uint8
    mesh.save("mesh.ply")

The stages one by one (the README's pipe):

    views = rt.clouds("cap/")                # rgbd-cloud cap/
    rt.clean_distance(views)                 # | rgbd-clean --distance
    rt.upsample(views, "cap/")               # | rgbd-upsample
    rt.align(views)                          # | rgbd-align
    rt.clean_density(views)                  # | rgbd-clean --density
    rt.fill(views)                           # | rgbd-fill
    mesh = rt.mesh(views, watertight=True)   # | rgbd-mesh --watertight
    rt.texture(mesh, "cap/", "model.obj", views=views)  # rgbd-texture --views

The compiled extension _rgbd_toolkit holds the bindings; this package adds the Open3D
conversions (when open3d is importable), in pure Python.
"""

import numpy as _np

from ._rgbd_toolkit import (  # noqa: F401
    AlgorithmError,
    Capture,
    Frame,
    FrameSet,
    InputError,
    IoError,
    Mesh,
    PointCloud,
    Sensor,
    align,
    clean_density,
    clean_distance,
    clouds,
    evaluate,
    evaluate_poses,
    fill,
    mesh,
    read_capture,
    read_mesh,
    read_views,
    reconstruct,
    texture,
    upsample,
    write_views,
)

__all__ = [
    "AlgorithmError", "Capture", "Frame", "FrameSet", "InputError", "IoError", "Mesh",
    "PointCloud", "Sensor", "align", "clean_density", "clean_distance", "clouds", "evaluate",
    "evaluate_poses", "fill", "mesh", "read_capture", "read_mesh", "read_views", "reconstruct",
    "texture", "upsample", "write_views",
]


def _open3d():
    try:
        import open3d
    except ImportError as e:  # pragma: no cover - depends on the machine
        raise ImportError("to_open3d/from_open3d need open3d (Debian: python3-open3d)") from e
    return open3d


def _mesh_to_open3d(self):
    """This mesh as an open3d.geometry.TriangleMesh (vertex colours scaled to [0, 1])."""
    o3d = _open3d()
    out = o3d.geometry.TriangleMesh(
        o3d.utility.Vector3dVector(_np.array(self.vertices, dtype=_np.float64)),  # a writeable copy
        o3d.utility.Vector3iVector(_np.asarray(self.faces, dtype=_np.int32)))
    if self.colors is not None:
        out.vertex_colors = o3d.utility.Vector3dVector(self.colors.astype(_np.float64) / 255.0)
    if self.normals is not None:
        out.vertex_normals = o3d.utility.Vector3dVector(self.normals)
    return out


def _mesh_from_open3d(triangle_mesh):
    """A Mesh from an open3d.geometry.TriangleMesh (vertex colours rounded to uint8)."""
    vertices = _np.asarray(triangle_mesh.vertices)
    faces = _np.asarray(triangle_mesh.triangles)
    colors = None
    if triangle_mesh.has_vertex_colors():
        colors = _np.clip(_np.rint(_np.asarray(triangle_mesh.vertex_colors) * 255), 0, 255)
        colors = colors.astype(_np.uint8)
    return Mesh(vertices, faces, colors)


def _cloud_to_open3d(self):
    """This view as an open3d.geometry.PointCloud, in its own frame (see `frame`, `pose`)."""
    o3d = _open3d()
    out = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(self.points))
    if self.normals is not None:
        out.normals = o3d.utility.Vector3dVector(self.normals)
    if self.colors is not None:
        out.colors = o3d.utility.Vector3dVector(self.colors.astype(_np.float64) / 255.0)
    return out


def _cloud_from_open3d(point_cloud, pose=None):
    """A PointCloud from an open3d.geometry.PointCloud (colours rounded to uint8)."""
    points = _np.asarray(point_cloud.points)
    normals = _np.asarray(point_cloud.normals) if point_cloud.has_normals() else None
    colors = None
    if point_cloud.has_colors():
        colors = _np.clip(_np.rint(_np.asarray(point_cloud.colors) * 255), 0, 255)
        colors = colors.astype(_np.uint8)
    return PointCloud(points, normals, colors, pose)


Mesh.to_open3d = _mesh_to_open3d
Mesh.from_open3d = staticmethod(_mesh_from_open3d)
PointCloud.to_open3d = _cloud_to_open3d
PointCloud.from_open3d = staticmethod(_cloud_from_open3d)
