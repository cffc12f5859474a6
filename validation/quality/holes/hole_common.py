"""What the hole measurements (measure_boundary.py, measure_fill.py) share: their command line,
the built rgbd-fill, Poisson-disk samples of a mesh and the robust spacing of the samples.
Open3D and numpy (Debian's /usr/bin/python3)."""
import argparse
import os
import sys

import numpy as np
import open3d as o3d

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))


def argument_parser(doc, points, seed):
    """--build (the build folder), --data (the test data, ../shared/data beside the repository),
    --points (samples per mesh, default `points`), --seed (default `seed`) and --out (the JSON
    lines file of the results, rgbd_stream.write_json_lines); the script adds its own
    options."""
    ap = argparse.ArgumentParser(description=doc.split("\n")[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--data", default=os.path.join(ROOT, "..", "shared", "data"))
    ap.add_argument("--points", type=int, default=points)
    ap.add_argument("--seed", type=int, default=seed)
    ap.add_argument("--out", default=None, help="JSON lines file")
    return ap


def fill_tool(build):
    """The path of BUILD/bin/rgbd-fill; exits naming it when it is not built."""
    tool = os.path.join(build, "bin", "rgbd-fill")
    if not os.path.exists(tool):
        sys.exit(f"{tool}: not built (ninja -C {build} rgbd-fill)")
    return tool


def poisson_samples(mesh, points, seed):
    """About `points` samples of `mesh` by Open3D's Poisson-disk sampling with the random seed
    `seed` (near-uniform, like a scanner): an Open3D point cloud."""
    o3d.utility.random.seed(seed)
    return mesh.sample_points_poisson_disk(points, init_factor=5)


def robust_spacing(pcd, xyz):
    """The median over the points of `xyz` of the distance to their second-nearest point of the
    Open3D cloud `pcd`: the robust spacing when `xyz` are pcd's own points (the nearest is the
    point itself)."""
    tree = o3d.geometry.KDTreeFlann(pcd)
    return float(np.median([np.sqrt(tree.search_knn_vector_3d(p, 2)[2][1]) for p in xyz]))
