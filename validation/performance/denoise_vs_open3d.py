#!/usr/bin/python3
"""Speed of rgbd-clean --density against Open3D remove_statistical_outlier, in one run.

For each bust of measure_denoise.py (8-Kinect-v2 ring from rgbd-synth, rgbd-cloud with its
default crop, rgbd-align without --merge), times on the same merged cloud, alternating runs:
- ours, tool: `rgbd-clean --density` wall time (process start, PLY stream read and write
  included) and the filter's own time_s from --metrics;
- Open3D 0.16: remove_statistical_outlier(nb_neighbors=20, std_ratio=2.0) on the merged
  points (call only, the cloud already in memory; and with o3d.io.read_point_cloud of the same
  points as one binary PLY, so both sides pay for reading the input).
Prints medians over --repeat runs and the ratios Open3D / ours (> 1: ours faster; the target
is >= 2). Timings vary by up to 30% between identical runs on this machine: compare ratios of the
same run.

Usage: denoise_vs_open3d.py [--bin BUILD/bin] [--work DIR] [--repeat N] [--seed S]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
import open3d as o3d

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "../quality/denoise"))
from measure_denoise import BUSTS, read_stream, run  # noqa: E402


def wall(cmd):
    t = time.perf_counter()
    r = subprocess.run(cmd, shell=True, capture_output=True, text=True)
    dt = time.perf_counter() - t
    if r.returncode != 0:
        sys.exit(f"failed: {cmd}\n{r.stderr}")
    return dt


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bin", default=os.path.join(os.path.dirname(__file__), "../../build/bin"))
    ap.add_argument("--work", default=None)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--seed", default="1")
    a = ap.parse_args()
    b = os.path.abspath(a.bin)
    work = a.work or tempfile.mkdtemp(prefix="rgbd_denoise_speed_")
    os.makedirs(work, exist_ok=True)
    print(f"# work dir {work}; tools {b}; Open3D {o3d.__version__}; {os.cpu_count()} cores; "
          f"median of {a.repeat} alternating runs")
    print("| capture | points | ours: tool wall (s) | ours: filter time_s (s) | "
          "O3D SOR call (s) | O3D read + SOR (s) | ratio O3D call / ours wall | "
          "ratio O3D read+SOR / ours wall | ratio O3D call / ours filter |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for name, mesh, args in BUSTS:
        cap = os.path.join(work, name)
        if not os.path.exists(os.path.join(cap, "rig.json")):
            run(f"{b}/rgbd-synth {mesh} -o {cap} {' '.join(args)} --seed {a.seed} -q")
        aligned = os.path.join(work, f"{name}_aligned.ply")
        if not os.path.exists(aligned):
            run(f"{b}/rgbd-cloud {cap} -q | {b}/rgbd-align -q > {aligned}")
        docs = read_stream(aligned)
        xyz = np.concatenate([np.stack([d["x"], d["y"], d["z"]], 1) for _, d in docs])
        xyz = xyz.astype(np.float64)
        merged_ply = os.path.join(work, f"{name}_merged_xyz.ply")
        o3d.io.write_point_cloud(merged_ply, o3d.geometry.PointCloud(
            o3d.utility.Vector3dVector(xyz)), write_ascii=False)
        out = os.path.join(work, f"{name}_density.ply")
        metrics = os.path.join(work, f"{name}_density.json")
        ours_wall, ours_filter, o3d_call, o3d_read = [], [], [], []
        for _ in range(a.repeat):
            ours_wall.append(wall(f"{b}/rgbd-clean --density -q {aligned} --metrics {metrics} "
                                  f"> {out}"))
            ours_filter.append(json.load(open(metrics))["documents"][0]["time_s"])
            pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(xyz))
            t = time.perf_counter()
            pc.remove_statistical_outlier(nb_neighbors=20, std_ratio=2.0)
            o3d_call.append(time.perf_counter() - t)
            t = time.perf_counter()
            pc = o3d.io.read_point_cloud(merged_ply)
            pc.remove_statistical_outlier(nb_neighbors=20, std_ratio=2.0)
            o3d_read.append(time.perf_counter() - t)
        w, f, c, r = (float(np.median(v)) for v in (ours_wall, ours_filter, o3d_call, o3d_read))
        print(f"| {name} | {len(xyz)} | {w:.3f} | {f:.3f} | {c:.3f} | {r:.3f} | {c / w:.2f} | "
              f"{r / w:.2f} | {c / f:.2f} |")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
