#!/usr/bin/python3
"""Could the sensors have seen it? Splits a reconstruction's errors on a synthetic capture by what
the capture's depth images observed (issue 35: a target the observations cannot reach is not a
defect of the method).

    /usr/bin/python3 validation/quality/variety/unobserved.py MESH CAPTURE [--frame N]
        [--tau-mm 5] [--near-mm 3] [--json OUT]

CAPTURE is an rgbd-synth capture folder (rig.json with depth intrinsics, <sensor>/depth/*.png in
depth_scale units, gt/mesh.ply and gt/world_from_depth.json: the true poses, so calibration error
plays no part). Every sensor's depth image of frame N is back-projected into the world.

- missed: true-surface samples (100,000, area-uniform) farther than --tau-mm from the mesh (the
  completeness misses), counted by how many sensors measured a point within --near-mm of them:
  0 means no sensor ever observed that part of the object (a mouth cavity, a crease), so no
  method working from these observations can put surface there except by guessing.
- invented: centroids of the mesh's faces farther than --tau-mm from the truth, counted by how
  many sensors saw them as empty space (the sensor's measured depth along the ray lies beyond the
  point by more than 4 mm + 1% of the depth: its ray went through), and by how many saw nothing
  there at all (no depth): free-space evidence a carving step could use, and how strong it is.

Numbers only, on stdout (and --json); needs Debian's python3-open3d and numpy.
"""
import argparse
import json
import sys

import numpy as np
import open3d as o3d


def load_views(capture, frame):
    rig = json.load(open(f"{capture}/rig.json"))
    poses = json.load(open(f"{capture}/gt/world_from_depth.json"))
    views = []
    for s in rig["sensors"]:
        k = s["depth"]
        path = f"{capture}/{s['id']}/depth/{frame:06d}.png"
        depth = np.asarray(o3d.io.read_image(path)).astype(float) / s.get("depth_scale", 1000.0)
        views.append((s["id"], k, depth, np.array(poses[s["id"]], dtype=float)))
    return views


def observed_points(views):
    pts, owner = [], []
    for i, (_, k, depth, pose) in enumerate(views):
        v, u = np.nonzero(depth > 0)
        z = depth[v, u]
        p = np.c_[(u - k["cx"]) / k["fx"] * z, (v - k["cy"]) / k["fy"] * z, z]
        pts.append(p @ pose[:3, :3].T + pose[:3, 3])
        owner.append(np.full(len(p), i))
    return np.vstack(pts), np.concatenate(owner)


def seen_empty(views, points):
    empty = np.zeros(len(points), int)
    no_depth = np.zeros(len(points), int)
    for _, k, depth, pose in views:
        inv = np.linalg.inv(pose)
        p = points @ inv[:3, :3].T + inv[:3, 3]
        z = p[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.round(p[:, 0] / z * k["fx"] + k["cx"])
            v = np.round(p[:, 1] / z * k["fy"] + k["cy"])
        ok = (z > 0) & (u >= 0) & (u < k["width"]) & (v >= 0) & (v < k["height"])
        measured = np.zeros(len(points))
        measured[ok] = depth[v[ok].astype(int), u[ok].astype(int)]
        empty += ok & (measured > 0) & (measured > z + 0.004 + 0.01 * z)
        no_depth += ok & (measured == 0)
    return empty, no_depth


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("mesh")
    ap.add_argument("capture")
    ap.add_argument("--frame", type=int, default=0)
    ap.add_argument("--tau-mm", type=float, default=5.0)
    ap.add_argument("--near-mm", type=float, default=3.0)
    ap.add_argument("--json")
    a = ap.parse_args()
    o3d.utility.random.seed(1)  # the same surface samples on every run
    tau, near = a.tau_mm / 1000.0, a.near_mm / 1000.0
    mesh = o3d.io.read_triangle_mesh(a.mesh)
    truth = o3d.io.read_triangle_mesh(f"{a.capture}/gt/mesh.ply")
    if len(mesh.triangles) == 0 or len(truth.triangles) == 0:
        sys.exit(f"unobserved.py: {a.mesh} or {a.capture}/gt/mesh.ply has no triangles")
    views = load_views(a.capture, a.frame)

    # Missed true surface and whether any sensor observed it.
    # KDTreeFlann keeps a pointer into its cloud: every cloud is held in a variable.
    mesh_samples = mesh.sample_points_uniformly(1000000)
    mesh_tree = o3d.geometry.KDTreeFlann(mesh_samples)
    samples = np.asarray(truth.sample_points_uniformly(100000).points)
    d = np.array([np.sqrt(mesh_tree.search_knn_vector_3d(p, 1)[2][0]) for p in samples])
    missed = samples[d > tau]
    pts, owner = observed_points(views)
    observed = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    obs_tree = o3d.geometry.KDTreeFlann(observed)
    seen_by = []
    for p in missed:
        n, idx, _ = obs_tree.search_radius_vector_3d(p, near)
        seen_by.append(len(set(owner[list(idx)])) if n else 0)
    seen_by = np.bincount(np.array(seen_by, int), minlength=3) if len(missed) else np.zeros(3, int)

    # Invented faces and the free-space evidence against them.
    truth_samples = truth.sample_points_uniformly(2000000)
    truth_tree = o3d.geometry.KDTreeFlann(truth_samples)
    V, F = np.asarray(mesh.vertices), np.asarray(mesh.triangles)
    centres = V[F].mean(1)
    area = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
    dist = np.array([np.sqrt(truth_tree.search_knn_vector_3d(c, 1)[2][0]) for c in centres])
    invented = dist > tau
    empty, no_depth = seen_empty(views, centres[invented])
    weights = area[invented]
    total = max(weights.sum(), 1e-30)

    def share(mask):
        return float(weights[mask].sum() / total)

    result = {
        "mesh": a.mesh,
        "capture": a.capture,
        "tau_mm": a.tau_mm,
        "missed_share": float(len(missed) / len(samples)),
        "missed_observed_by": {"0": int(seen_by[0]), "1": int(seen_by[1]),
                               "2+": int(seen_by[2:].sum())},
        "missed_never_observed_share": float(seen_by[0] / max(len(missed), 1)),
        "invented_area_share": float(weights.sum() / max(area.sum(), 1e-30)),
        "invented_seen_empty_by": {"0": share(empty == 0), "1": share(empty == 1),
                                   "2+": share(empty >= 2)},
        "invented_no_depth_in_some_view": share(no_depth > 0),
    }
    text = json.dumps(result, indent=1)
    print(text)
    if a.json:
        open(a.json, "w").write(text + "\n")


if __name__ == "__main__":
    main()
