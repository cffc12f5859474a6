#!/usr/bin/python3
"""Open3D 0.16 Screened Poisson (python3-open3d), the peer of rgbd-eval --baseline.

Reads the points rgbd-eval wrote (binary little-endian PLY: float x y z, float nx ny nz,
float sx sy sz = position of the point's sensor (NaN when unknown), uchar red green blue;
`comment normals given` or `comment normals missing`), estimates normals when missing the way
the peer pipeline of docs/method.md does (Open3D estimate_normals, hybrid search radius 4 x the median
nearest-neighbour spacing, 30 neighbours, each normal turned towards its sensor; without a
sensor, away from the centroid), then runs TriangleMesh.create_from_point_cloud_poisson at
each depth (Open3D's defaults: scale 1.1, samples per node 1.5, point weight 2), optionally
trims vertices below a density quantile, and writes OUT_DIR/spr_d<depth>.ply. One JSON line
per depth on stdout: depth, time_s (Poisson + trim), normals_time_s, vertices, triangles, file.
Exit code 3 when open3d cannot be imported. --threads is Open3D's n_threads (-1: all cores);
its multi-threaded solver crashes now and then (a race: Open3D issue 6828, PoissonRecon issue
298), and rgbd-eval then runs this script again with --threads 1.

Usage: open3d_screened_poisson.py --input POINTS.ply --out-dir DIR [--depths 8,9,10]
                                  [--trim-quantile 0.02] [--threads N]
"""
import argparse
import json
import os
import sys
import time

import numpy as np

# Open3D's OpenMP threads spin while they wait by default; on a shared machine (or next to
# another OpenMP process) that makes Poisson many times slower (12k points at depth 6: 40 s
# instead of 2.5 s on 2 busy cores). Sleep instead, unless the caller chose otherwise.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
try:
    import open3d as o3d
except ImportError:
    print("open3d_screened_poisson.py: python3-open3d is not installed "
          "(apt-get install python3-open3d)", file=sys.stderr)
    sys.exit(3)

TYPES = {"float": "<f4", "uchar": "u1", "double": "<f8", "int": "<i4", "uint": "<u4"}


def read_points(path):
    data = open(path, "rb").read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    fields, count, normals_given = [], 0, False
    for line in data[:end].decode("ascii").splitlines():
        parts = line.split()
        if parts[:2] == ["element", "vertex"]:
            count = int(parts[2])
        elif parts[:1] == ["property"]:
            fields.append((parts[2], TYPES[parts[1]]))
        elif parts[:3] == ["comment", "normals", "given"]:
            normals_given = True
    v = np.frombuffer(data, dtype=np.dtype(fields), count=count, offset=end)
    xyz = np.stack([v["x"], v["y"], v["z"]], 1).astype(np.float64)
    nrm = np.stack([v["nx"], v["ny"], v["nz"]], 1).astype(np.float64)
    sen = np.stack([v["sx"], v["sy"], v["sz"]], 1).astype(np.float64)
    rgb = np.stack([v["red"], v["green"], v["blue"]], 1).astype(np.float64) / 255.0
    return xyz, (nrm if normals_given else None), sen, rgb


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--input", required=True)
    ap.add_argument("--out-dir", required=True)
    ap.add_argument("--depths", default="8,9,10")
    ap.add_argument("--trim-quantile", type=float, default=0.0)
    ap.add_argument("--no-colors", action="store_true")
    ap.add_argument("--threads", type=int, default=-1,
                    help="Open3D's n_threads for Poisson (-1: all cores)")
    a = ap.parse_args()
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    xyz, nrm, sen, rgb = read_points(a.input)
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(xyz))
    if not a.no_colors:
        pcd.colors = o3d.utility.Vector3dVector(rgb)
    t0 = time.perf_counter()
    if nrm is not None:
        pcd.normals = o3d.utility.Vector3dVector(nrm)
    else:
        spacing = float(np.median(np.asarray(pcd.compute_nearest_neighbor_distance())))
        pcd.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=4 * spacing, max_nn=30))
        n = np.asarray(pcd.normals)
        towards = sen - xyz
        unknown = ~np.isfinite(towards).all(1)
        towards[unknown] = xyz[unknown] - xyz.mean(0)  # no sensor: away from the centroid
        flip = np.einsum("ij,ij->i", n, towards) < 0
        n[flip] *= -1
        pcd.normals = o3d.utility.Vector3dVector(n)
    normals_time = time.perf_counter() - t0
    for d in [int(x) for x in a.depths.split(",")]:
        t0 = time.perf_counter()
        mesh, dens = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
            pcd, depth=d, n_threads=a.threads)
        if a.trim_quantile > 0:
            dens = np.asarray(dens)
            mesh.remove_vertices_by_mask(dens < np.quantile(dens, a.trim_quantile))
        elapsed = time.perf_counter() - t0
        out = os.path.join(a.out_dir, f"spr_d{d}.ply")
        if not o3d.io.write_triangle_mesh(out, mesh, write_ascii=False):
            print(f"open3d_screened_poisson.py: cannot write {out}", file=sys.stderr)
            sys.exit(1)
        print(json.dumps({"depth": d, "time_s": elapsed, "normals_time_s": normals_time,
                          "vertices": len(mesh.vertices), "triangles": len(mesh.triangles),
                          "file": out}), flush=True)


if __name__ == "__main__":
    main()
