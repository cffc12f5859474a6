#!/usr/bin/python3
"""Pair ICP speed: rgbd-align's point-to-plane ICP against Open3D 0.16 registration_icp
(TransformationEstimationPointToPlane) at equal input and iterations, ratio printed.

Input: two neighbouring views (45 degrees apart) of an 8-Kinect rgbd-synth ring of the Max Planck
bust (rgbd-cloud | rgbd-clean --distance), voxel-down-sampled by Open3D (default 5 mm), normals
by Open3D (hybrid radius 4 voxels, 30 neighbours, towards the camera), the source moved into the
target frame with the rig poses; both clouds written as PLY with normals and read by both
programs. Each side runs exactly N iterations at one correspondence distance (convergence tests
off), R repeats, median time; with all threads and with one. Ours also applies its robust Tukey
kernel and its 60-degree normal gate (what rgbd-align runs); Open3D runs plain point-to-plane.

Usage: icp_vs_open3d.py [--build build] [--work DIR] [--iterations 30] [--repeats 7]
                        [--distance 0.012] [--voxel 0.005]
"""
import argparse
import json
import os
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "quality",
                                "common"))
from open3d_peer import o3d_view_cloud  # noqa: E402
from rgbd_stream import pose_of, read_stream, run, work_folder  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
MESH = os.path.join(HERE, "..", "..", "..", "shared", "data", "meshes", "max_planck",
                    "max-planck.obj")

O3D_TIMER = r"""
import json, sys, time
import numpy as np
import open3d as o3d
src = o3d.io.read_point_cloud(sys.argv[1]); tgt = o3d.io.read_point_cloud(sys.argv[2])
d, n, r = float(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5])
reg = o3d.pipelines.registration
times = []
for _ in range(r):
    t0 = time.perf_counter()
    res = reg.registration_icp(src, tgt, d, np.eye(4), reg.TransformationEstimationPointToPlane(),
                               reg.ICPConvergenceCriteria(0.0, 0.0, n))
    times.append(time.perf_counter() - t0)
print(json.dumps({"seconds": sorted(times)[len(times) // 2], "fitness": res.fitness,
                  "inlier_rmse": res.inlier_rmse, "points": len(src.points)}))
"""


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--build", default="build")
    ap.add_argument("--work", default=None)
    ap.add_argument("--iterations", type=int, default=30)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--distance", type=float, default=0.012)
    ap.add_argument("--voxel", type=float, default=0.005)
    a = ap.parse_args()
    work = work_folder("icp_vs_open3d", a.work, needs=MESH)
    import open3d as o3d
    build = os.path.abspath(a.build)
    run(f"cmake --build {build} --target icp_pair_timer rgbd-synth rgbd-cloud rgbd-clean "
        f"> {work}/build.log 2>&1")
    b = os.path.join(build, "bin")
    cap = os.path.join(work, "cap")
    if not os.path.isdir(cap):
        run(f"{b}/rgbd-synth {MESH} -o {cap} -q --height-m 0.6 --seed 1")
    run(f"{b}/rgbd-cloud {cap} | {b}/rgbd-clean --distance -q > {work}/views.ply")
    docs = read_stream(f"{work}/views.ply")
    clouds = [o3d_view_cloud(d, a.voxel) for _, d in docs[:2]]
    target_pose, source_pose = pose_of(docs[0][0]), pose_of(docs[1][0])
    clouds[1].transform(np.linalg.inv(target_pose) @ source_pose)  # rig: roughly aligned
    src, tgt = f"{work}/source.ply", f"{work}/target.ply"
    o3d.io.write_point_cloud(src, clouds[1])
    o3d.io.write_point_cloud(tgt, clouds[0])
    with open(f"{work}/o3d_timer.py", "w") as f:
        f.write(O3D_TIMER)
    args = f"{src} {tgt} {a.distance} {a.iterations} {a.repeats}"
    print(f"input: {len(clouds[1].points)} source / {len(clouds[0].points)} target points, "
          f"{a.iterations} iterations at {a.distance * 1000:.0f} mm, median of {a.repeats}")
    print("| threads | ours s | Open3D s | ratio (Open3D / ours) | ours fitness / rmse mm | "
          "Open3D fitness / rmse mm |")
    print("|---|---|---|---|---|---|")
    for threads in (0, 1):
        env = dict(os.environ)
        if threads:
            env["OMP_NUM_THREADS"] = str(threads)
        ours = json.loads(subprocess.run(f"{b}/icp_pair_timer {args} {threads}", shell=True,
                                         capture_output=True, text=True, check=True).stdout)
        theirs = json.loads(subprocess.run(f"/usr/bin/python3 {work}/o3d_timer.py {args}",
                                           shell=True, capture_output=True, text=True, env=env,
                                           check=True).stdout)
        print(f"| {threads or 'all'} | {ours['seconds']:.4f} | {theirs['seconds']:.4f} | "
              f"{theirs['seconds'] / ours['seconds']:.2f} | {ours['fitness']:.3f} / "
              f"{1000 * ours['inlier_rmse']:.2f} | {theirs['fitness']:.3f} / "
              f"{1000 * theirs['inlier_rmse']:.2f} |", flush=True)


if __name__ == "__main__":
    main()
