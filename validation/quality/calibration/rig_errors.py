#!/usr/bin/env python3
"""Errors of a calibrated rig.json against a synthetic capture's truth (issue 19 targets).

Errors are relative to the anchor sensor (the gauge): the estimated rig is moved so that the
anchor sits at its true pose, then for every sensor
  - rotation error (deg) of world_from_depth,
  - RMS displacement (mm) of points that the sensor maps: points p of a ball of radius --radius-m
    (default 0.3) around the capture's centre (gt/scene.json: ring_centre, or the mesh's
    object_centre), moved by  gt_world_from_est_world * est_world_from_depth * true_depth_from_world,
    i.e. where the sensor's data would land with the estimated rig instead of the true one,
  - with --mesh, the same RMS over the vertices of gt/mesh.ply (the object's surface).
Prints one line per sensor and a summary line; --json FILE writes them.
Usage: rig_errors.py CAPTURE RIG_JSON [--anchor ID] [--radius-m R] [--mesh] [--json FILE]
"""
import argparse
import json
import math
import os
import sys

import numpy as np


def pose(m):
    return np.array(m, dtype=float).reshape(4, 4)


def load_rig(path):
    with open(path) as f:
        rig = json.load(f)
    return {s["id"]: pose(s["world_from_depth"]) for s in rig["sensors"]}


def rot_deg(a, b):
    r = a[:3, :3] @ b[:3, :3].T
    return math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(r) - 1) / 2))))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("capture")
    ap.add_argument("rig")
    ap.add_argument("--anchor")
    ap.add_argument("--radius-m", type=float, default=0.3)
    ap.add_argument("--mesh", action="store_true")
    ap.add_argument("--json")
    a = ap.parse_args()
    with open(os.path.join(a.capture, "gt", "world_from_depth.json")) as f:
        truth = {k: pose(v) for k, v in json.load(f).items()}
    with open(os.path.join(a.capture, "gt", "scene.json")) as f:
        scene = json.load(f)
    centre = np.array(scene.get("ring_centre") or scene["mesh"]["object_centre"], dtype=float)
    est = load_rig(a.rig)
    ids = list(est.keys())
    anchor = a.anchor or ids[0]
    gauge = truth[anchor] @ np.linalg.inv(est[anchor])  # true world <- estimated world
    rng = np.random.default_rng(1)
    pts = rng.uniform(-1, 1, size=(20000, 3))
    pts = pts[np.linalg.norm(pts, axis=1) <= 1][:5000] * a.radius_m + centre
    surface = None
    if a.mesh:
        import open3d as o3d
        surface = np.asarray(o3d.io.read_triangle_mesh(
            os.path.join(a.capture, "gt", "mesh.ply")).vertices)
    rows = []
    for i in ids:
        moved = gauge @ est[i] @ np.linalg.inv(truth[i])
        def rms(p):
            q = p @ moved[:3, :3].T + moved[:3, 3]
            return 1e3 * math.sqrt(np.mean(np.sum((q - p) ** 2, axis=1)))
        row = {"id": i, "rotation_deg": rot_deg(gauge @ est[i], truth[i]), "ball_rms_mm": rms(pts)}
        if surface is not None:
            row["surface_rms_mm"] = rms(surface)
        rows.append(row)
        print(f"{i:12s} rot {row['rotation_deg']:.4f} deg  ball {row['ball_rms_mm']:.3f} mm" +
              (f"  surface {row['surface_rms_mm']:.3f} mm" if surface is not None else ""))
    worst = {k: max(r[k] for r in rows) for k in rows[0] if k != "id"}
    print("worst: " + "  ".join(f"{k} {v:.4f}" for k, v in worst.items()))
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"sensors": rows, "worst": worst, "anchor": anchor,
                       "radius_m": a.radius_m}, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
