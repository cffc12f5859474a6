#!/usr/bin/python3
"""Open3D 0.16 peers of rgbd-eval --observed --baseline (python3-open3d): TSDF fusion and
Screened Poisson on a capture's observed subject points.

Reads what rgbd-eval wrote: POINTS.ply (binary little-endian; float x y z and nx ny nz in the
world frame, normals oriented towards each point's camera; int view; uchar red green blue)
and VIEWS.json ({"views": [{"width", "height", "fx", "fy", "cx", "cy", "world_from_sensor":
4x4 row-major}]}, one per view id: the pinhole of the depth camera, distortion already removed
by rgbd-eval's back-projection).

--method tsdf: each view's points are projected back into an undistorted depth image of its
camera (pinhole, nearest point wins) with their colours, so only the observed subject pixels
hold depth; Open3D's ScalableTSDFVolume (voxel --voxel m, sdf_trunc --trunc-voxels voxels,
colour RGB8) integrates them with extrinsic = sensor_from_world; extract_triangle_mesh.
--method screened-poisson: TriangleMesh.create_from_point_cloud_poisson on all points with
their normals at --depth (Open3D's defaults: scale 1.1, samples per node 1.5, point weight 2),
then vertices below the --trim-quantile density quantile removed (0: none).

Writes --out (PLY) and prints one JSON line: method, time_s, vertices, triangles, file. Exit
code 3 when open3d cannot be imported. Open3D's multi-threaded Poisson crashes now and then
(Open3D issue 6828); rgbd-eval then runs this again with --threads 1.

Usage: open3d_observed.py --points POINTS.ply --views VIEWS.json --method tsdf|screened-poisson
                          --out MESH.ply [--voxel 0.006] [--trunc-voxels 4] [--depth 9]
                          [--trim-quantile 0.02] [--threads N]
"""
import argparse
import json
import os
import sys
import time

import numpy as np

# Sleep instead of spinning while OpenMP threads wait (see open3d_screened_poisson.py).
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
try:
    import open3d as o3d
except ImportError:
    print("open3d_observed.py: python3-open3d is not installed (apt-get install python3-open3d)",
          file=sys.stderr)
    sys.exit(3)

TYPES = {"float": "<f4", "uchar": "u1", "double": "<f8", "int": "<i4", "uint": "<u4"}


def read_points(path):
    data = open(path, "rb").read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    fields, count = [], 0
    for line in data[:end].decode("ascii").splitlines():
        parts = line.split()
        if parts[:2] == ["element", "vertex"]:
            count = int(parts[2])
        elif parts[:1] == ["property"]:
            fields.append((parts[2], TYPES[parts[1]]))
    v = np.frombuffer(data, dtype=np.dtype(fields), count=count, offset=end)
    xyz = np.stack([v["x"], v["y"], v["z"]], 1).astype(np.float64)
    nrm = np.stack([v["nx"], v["ny"], v["nz"]], 1).astype(np.float64)
    rgb = np.stack([v["red"], v["green"], v["blue"]], 1)
    return xyz, nrm, np.asarray(v["view"]), rgb


def view_images(xyz, rgb, view):
    """The depth (float32, metres, 0 = none) and colour (uint8 RGB) images of one view's
    points seen by its pinhole camera; the nearest point wins a pixel."""
    w, h = view["width"], view["height"]
    pose = np.asarray(view["world_from_sensor"], dtype=np.float64).reshape(4, 4)
    sensor_from_world = np.linalg.inv(pose)
    p = xyz @ sensor_from_world[:3, :3].T + sensor_from_world[:3, 3]
    z = p[:, 2]
    ok = z > 0
    u = np.rint(view["fx"] * p[ok, 0] / z[ok] + view["cx"]).astype(np.int64)
    v = np.rint(view["fy"] * p[ok, 1] / z[ok] + view["cy"]).astype(np.int64)
    zz, cc = z[ok], rgb[ok]
    inside = (u >= 0) & (u < w) & (v >= 0) & (v < h)
    u, v, zz, cc = u[inside], v[inside], zz[inside], cc[inside]
    order = np.argsort(-zz)  # far first: the nearest point is written last and wins
    depth = np.zeros((h, w), np.float32)
    color = np.zeros((h, w, 3), np.uint8)
    depth[v[order], u[order]] = zz[order]
    color[v[order], u[order]] = cc[order]
    return depth, color, sensor_from_world


def tsdf(xyz, rgb, ids, views, voxel, trunc_voxels):
    volume = o3d.pipelines.integration.ScalableTSDFVolume(
        voxel_length=voxel, sdf_trunc=trunc_voxels * voxel,
        color_type=o3d.pipelines.integration.TSDFVolumeColorType.RGB8)
    for k, view in enumerate(views):
        sel = ids == k
        if not sel.any():
            continue
        depth, color, extrinsic = view_images(xyz[sel], rgb[sel], view)
        rgbd = o3d.geometry.RGBDImage.create_from_color_and_depth(
            o3d.geometry.Image(color), o3d.geometry.Image(depth), depth_scale=1.0,
            depth_trunc=float(depth.max()) + 1.0, convert_rgb_to_intensity=False)
        intrinsic = o3d.camera.PinholeCameraIntrinsic(view["width"], view["height"], view["fx"],
                                                      view["fy"], view["cx"], view["cy"])
        volume.integrate(rgbd, intrinsic, extrinsic)
    return volume.extract_triangle_mesh()


def screened_poisson(xyz, nrm, rgb, depth, trim, threads):
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(xyz))
    pcd.normals = o3d.utility.Vector3dVector(nrm)
    pcd.colors = o3d.utility.Vector3dVector(rgb.astype(np.float64) / 255.0)
    mesh, dens = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
        pcd, depth=depth, n_threads=threads)
    if trim > 0:
        dens = np.asarray(dens)
        mesh.remove_vertices_by_mask(dens < np.quantile(dens, trim))
    return mesh


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", required=True)
    ap.add_argument("--views", required=True)
    ap.add_argument("--method", required=True, choices=["tsdf", "screened-poisson"])
    ap.add_argument("--out", required=True)
    ap.add_argument("--voxel", type=float, default=0.006)
    ap.add_argument("--trunc-voxels", type=float, default=4.0)
    ap.add_argument("--depth", type=int, default=9)
    ap.add_argument("--trim-quantile", type=float, default=0.0)
    ap.add_argument("--threads", type=int, default=-1,
                    help="Open3D's n_threads for Poisson (-1: all cores)")
    a = ap.parse_args()
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    xyz, nrm, ids, rgb = read_points(a.points)
    with open(a.views) as f:
        views = json.load(f)["views"]
    t0 = time.perf_counter()
    if a.method == "tsdf":
        mesh = tsdf(xyz, rgb, ids, views, a.voxel, a.trunc_voxels)
    else:
        mesh = screened_poisson(xyz, nrm, rgb, a.depth, a.trim_quantile, a.threads)
    elapsed = time.perf_counter() - t0
    # Zero-area triangles would make later distance queries abort (Open3D 0.16); drop them
    # with the other degenerate parts, which changes no area.
    mesh.remove_degenerate_triangles()
    mesh.remove_unreferenced_vertices()
    if not o3d.io.write_triangle_mesh(a.out, mesh, write_ascii=False):
        print(f"open3d_observed.py: cannot write {a.out}", file=sys.stderr)
        sys.exit(1)
    print(json.dumps({"method": a.method, "time_s": elapsed, "vertices": len(mesh.vertices),
                      "triangles": len(mesh.triangles), "file": a.out}), flush=True)


if __name__ == "__main__":
    main()
