#!/usr/bin/python3
"""Hole-rim (boundary) detection on meshes with known holes (docs/algorithms.md §10), ours against the
peers in the same run.

Meshes: shared/data/meshes/cgal_with_holes/{head,holes,mech-holes-shark}.off and the Stanford
bunny (its 5 scanner holes are open boundaries of the mesh). Each mesh is sampled to points with
Open3D's Poisson-disk sampling (near-uniform, like a scanner; --points per mesh, fixed seed).
Every method gets the same points and the same normals (PCA over 16 neighbours, Open3D
estimate_normals), so only the boundary criterion differs.

Truth: the distance d of each sample to the mesh's boundary edges (edges used by one
triangle), in units of the robust spacing s (median nearest-neighbour distance of the samples).
Rim points: d < 0.5 s (nothing can lie between them and the rim); closed region: d > 3 s.
Points in between are not scored. Reported per method: recall = flagged share of the rim points,
false rate = flagged share of the closed-region points.

Methods:
  ours    rgbd-fill --detect-only --mark (angle + half-disk + shape, coherence, loops >= 8 points)
  open3d  t.geometry.PointCloud.compute_boundary_points(radius, max_nn=30, angle_threshold=90)
  pcl     pcl::BoundaryEstimation (angle criterion, pi/2) via pcl_boundary (this folder; build
          target pcl_boundary when libpcl-dev is installed, or --pcl PATH)
Peers run at radius 1.5, 2.5 and 4 s; the summary compares ours with each peer's best radius
(highest recall - false rate).

Usage: validation/quality/holes/measure_boundary.py [--build build] [--points 30000]
       [--out results.jsonl]
"""
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
import open3d as o3d

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
import rgbd_stream  # noqa: E402
from hole_common import argument_parser, fill_tool, poisson_samples, robust_spacing

MESHES = ["cgal_with_holes/head.off", "cgal_with_holes/holes.off",
          "cgal_with_holes/mech-holes-shark.off", "stanford_bunny/stanford-bunny.obj"]
PEER_RADII = [1.5, 2.5, 4.0]


def boundary_edges(mesh):
    t = np.asarray(mesh.triangles)
    e = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    u, c = np.unique(e, axis=0, return_counts=True)
    return u[c == 1]


def segment_distance(points, a, b, chunk=4096):
    """Distance of each point to the nearest of the segments a[i]-b[i]."""
    out = np.full(len(points), np.inf)
    ab = b - a
    ab2 = np.maximum((ab * ab).sum(1), 1e-300)
    for s in range(0, len(points), chunk):
        p = points[s:s + chunk, None, :]
        t = np.clip(((p - a[None]) * ab[None]).sum(2) / ab2[None], 0.0, 1.0)
        q = a[None] + t[..., None] * ab[None]
        out[s:s + chunk] = np.sqrt(((p - q) ** 2).sum(2)).min(1)
    return out




def ours(xyz, normals, tool, tmp):
    src, dst = os.path.join(tmp, "in.ply"), os.path.join(tmp, "out.ply")
    rgbd_stream.write_points(src, xyz, normals=normals)
    t0 = time.time()
    rgbd_stream.run(f"{tool} --detect-only --mark -q {src} -o {dst}")
    elapsed = time.time() - t0
    docs = rgbd_stream.read_stream(dst)
    return docs[0][1]["boundary"].astype(bool), elapsed


def open3d_boundary(xyz, normals, radius):
    pcd = o3d.t.geometry.PointCloud(o3d.core.Tensor(xyz, o3d.core.float64))
    pcd.point["normals"] = o3d.core.Tensor(normals, o3d.core.float64)
    t0 = time.time()
    _, mask = pcd.compute_boundary_points(radius, 30, 90.0)
    return mask.numpy().astype(bool), time.time() - t0


def pcl_boundary(xyz, normals, radius, binary, tmp):
    path = os.path.join(tmp, "pcl.bin")
    np.hstack([xyz, normals]).astype("<f8").tofile(path)
    t0 = time.time()
    r = subprocess.run([binary, path, repr(radius)], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"pcl_boundary failed: {r.stderr}")
    flags = np.array([c == "1" for c in r.stdout.split()], dtype=bool)
    return flags, time.time() - t0


def main():
    ap = argument_parser(__doc__, points=30000, seed=1)
    ap.add_argument("--pcl", default=None, help="pcl_boundary binary (default: BUILD/bin)")
    args = ap.parse_args()
    tool = fill_tool(args.build)
    pcl = args.pcl or os.path.join(args.build, "bin", "pcl_boundary")
    if not os.path.exists(pcl):
        print(f"note: {pcl} not found (needs libpcl-dev: ninja -C build pcl_boundary); PCL "
              "skipped", file=sys.stderr)
        pcl = None
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in MESHES:
            path = os.path.join(args.data, "meshes", name)
            if not os.path.exists(path):
                print(f"skip {name}: {path} missing", file=sys.stderr)
                continue
            mesh = o3d.io.read_triangle_mesh(path)
            mesh.remove_duplicated_vertices()
            mesh.remove_duplicated_triangles()
            mesh.remove_degenerate_triangles()
            edges = boundary_edges(mesh)
            v = np.asarray(mesh.vertices)
            pcd = poisson_samples(mesh, args.points, args.seed)
            xyz = np.asarray(pcd.points).astype(np.float64)
            pcd.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(16))
            normals = np.asarray(pcd.normals).astype(np.float64)
            s = robust_spacing(pcd, xyz)
            d = segment_distance(xyz, v[edges[:, 0]], v[edges[:, 1]]) / s
            rim, closed = d < 0.5, d > 3.0
            row = {"mesh": name, "points": len(xyz), "spacing": s,
                   "boundary_edges": int(len(edges)), "rim_points": int(rim.sum()),
                   "closed_points": int(closed.sum()), "methods": {}}

            def score(flags, elapsed):
                return {"recall": float(flags[rim].mean()),
                        "false_rate": float(flags[closed].mean()),
                        "flagged": int(flags.sum()), "time_s": round(elapsed, 3)}

            row["methods"]["ours"] = score(*ours(xyz, normals, tool, tmp))
            for r in PEER_RADII:
                row["methods"][f"open3d_r{r}"] = score(*open3d_boundary(xyz, normals, r * s))
                if pcl:
                    row["methods"][f"pcl_r{r}"] = score(*pcl_boundary(xyz, normals, r * s, pcl,
                                                                      tmp))
            results.append(row)
            print(f"{name}: {len(xyz)} points, spacing {s:.4g}, {rim.sum()} rim / "
                  f"{closed.sum()} closed-region points")
            for m, v_ in row["methods"].items():
                print(f"  {m:12s} recall {v_['recall']:.3f}  false rate {v_['false_rate']:.4f}  "
                      f"({v_['flagged']} flagged, {v_['time_s']} s)")
            for peer in ["open3d", "pcl"]:
                cands = {k: v_ for k, v_ in row["methods"].items() if k.startswith(peer)}
                if not cands:
                    continue
                best = max(cands, key=lambda k: cands[k]["recall"] - cands[k]["false_rate"])
                o = row["methods"]["ours"]
                b = cands[best]
                better = o["recall"] >= b["recall"] and o["false_rate"] <= b["false_rate"]
                row[f"vs_{peer}"] = {"best": best, "ours_dominates": bool(better)}
                print(f"  vs {peer} best ({best}): recall {o['recall']:.3f} vs {b['recall']:.3f}, "
                      f"false {o['false_rate']:.4f} vs {b['false_rate']:.4f} -> "
                      f"{'ours better on both' if better else 'not better on both'}")
            o = row["methods"]["ours"]
            row["target_met"] = bool(o["recall"] >= 0.95 and o["false_rate"] <= 0.02)
            print(f"  target (recall >= 0.95, false <= 0.02): "
                  f"{'met' if row['target_met'] else 'NOT met'}")
    rgbd_stream.write_json_lines(args.out, results)


if __name__ == "__main__":
    main()
