#!/usr/bin/python3
"""Multi-view alignment accuracy of rgbd-align against Open3D 0.16 (issue 5).

For every bust and seed: rgbd-synth renders an 8-Kinect ring whose rig.json poses carry a
calibration error (default 5 degrees and 50 mm on every sensor but sensor 0); rgbd-cloud |
rgbd-clean --distance gives the input every method gets (views in their sensor frames, the
erroneous rig poses as initial poses). Methods, timed in the same run:
- ours: rgbd-align (pairwise stage with FPFH + RANSAC hypotheses, pose graph, joint rounds);
- o3d-p2plane: Open3D point-to-plane ICP between ring neighbours from the rig poses
  (coarse to fine 48/24/12/6 mm, 40/40/40/30 iterations, 5 mm voxel), then Open3D's pose graph
  (global_optimization, Levenberg-Marquardt, edge prune 0.25, reference node 0): the peer pipeline's
  pipeline;
- o3d-colored: the same with registration_colored_icp (3 scales, 20/10/5 mm voxel, 50/30/14
  iterations, the Open3D tutorial schedule).
Errors after removing the global gauge (the rigid motion that best maps the estimated object
points onto the true ones, Umeyama): per sensor rotation error (degrees), translation error of
the sensor centre (mm), and translation at the object (RMS displacement of the view's own
points, mm). A seed succeeds when every sensor is within 0.2 degrees and 1.5 mm.

With --uva: the real person sequence (shared/data/multiview/uva_cv2_person_kinect1, 50 frames
around 360 degrees, per-frame pseudo ground truth good to 3-5 mm): rgbd-align --ignore-poses
(no initial poses at all) against Open3D point-to-plane ICP between consecutive frames from the
identity plus its pose graph; relative pose error of every consecutive pair against the pseudo
ground truth (median, p90) and the 360-degree loop closure before / after.

Usage: measure_align.py [--bin build/bin] [--work DIR] [--seeds 20] [--calib-deg 5]
                        [--calib-mm 50] [--busts max_planck,bust_man_wreath] [--uva]
"""
import json
import os
import sys
import time

import numpy as np
import open3d as o3d

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
from open3d_peer import o3d_view_cloud, optimise  # noqa: E402
from rgbd_stream import (argument_parser, BUSTS, DATA, meta, pose_of, read_stream, run,  # noqa: E402
                         work_folder, xyz_of)



def umeyama(src, dst):
    """4x4 rigid transform minimising |T src - dst| (rows are points)."""
    ms, md = src.mean(0), dst.mean(0)
    h = (src - ms).T @ (dst - md)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1, 1, d]) @ u.T
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = r, md - r @ ms
    return t


def apply(t, p):
    return p @ t[:3, :3].T + t[:3, 3]


def pose_errors(est, truth, pts):
    """Per-sensor (rotation deg, centre mm, object mm) after the object gauge."""
    keys = sorted(est)
    src = np.concatenate([apply(est[k], pts[k]) for k in keys])
    dst = np.concatenate([apply(truth[k], pts[k]) for k in keys])
    g = umeyama(src, dst)
    out = {}
    for k in keys:
        a = g @ est[k]
        r = a[:3, :3] @ truth[k][:3, :3].T
        rot = np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1)))
        centre = 1000 * np.linalg.norm(a[:3, 3] - truth[k][:3, 3])
        obj = 1000 * np.sqrt(np.mean(np.sum((apply(a, pts[k]) - apply(truth[k], pts[k])) ** 2, 1)))
        out[k] = (rot, centre, obj)
    return out


def o3d_p2plane(src, tgt, t):
    """The peer pipeline's coarse-to-fine point-to-plane ICP: 48/24/12/6 mm, 40/40/40/30 iterations."""
    reg = o3d.pipelines.registration
    for d, it in [(0.048, 40), (0.024, 40), (0.012, 40), (0.006, 30)]:
        t = reg.registration_icp(src, tgt, d, t, reg.TransformationEstimationPointToPlane(),
                                 reg.ICPConvergenceCriteria(1e-6, 1e-6, it)).transformation
    return t


def o3d_ring(docs, colored):
    """Open3D ring neighbours + pose graph from the rig poses; world_from_sensor per view."""
    reg = o3d.pipelines.registration
    n = len(docs)
    init = [pose_of(c) for c, _ in docs]
    if colored:
        scales = [(0.02, 50), (0.01, 30), (0.005, 14)]
        clouds = {v: [o3d_view_cloud(d, v) for _, d in docs] for v, _ in scales}
    else:
        clouds = [o3d_view_cloud(d, 0.005) for _, d in docs]
    graph = reg.PoseGraph()
    for p in init:
        graph.nodes.append(reg.PoseGraphNode(p))
    for i in range(n):
        j = (i + 1) % n  # source j, target i
        t = np.linalg.inv(init[i]) @ init[j]
        if colored:
            for v, it in scales:
                try:  # raises when no correspondence is within reach: keep the pose
                    t = reg.registration_colored_icp(
                        clouds[v][j], clouds[v][i], v, t,
                        reg.TransformationEstimationForColoredICP(),
                        reg.ICPConvergenceCriteria(1e-6, 1e-6, it)).transformation
                except RuntimeError:
                    pass
            src, tgt = clouds[0.005][j], clouds[0.005][i]
        else:
            t = o3d_p2plane(clouds[j], clouds[i], t)
            src, tgt = clouds[j], clouds[i]
        info = reg.get_information_matrix_from_point_clouds(src, tgt, 0.012, t)
        graph.edges.append(reg.PoseGraphEdge(j, i, t, info, uncertain=(j == 0)))
    optimise(graph)
    return [np.asarray(node.pose) for node in graph.nodes]


def summarise(rows, name):
    """rows: [(seed, {sensor: (rot, centre, obj)}, seconds)]"""
    worst = np.array([[max(e[0] for e in r.values()), max(e[1] for e in r.values()),
                       max(e[2] for e in r.values())] for _, r, _ in rows])
    ok_centre = np.mean((worst[:, 0] <= 0.2) & (worst[:, 1] <= 1.5))
    ok_object = np.mean((worst[:, 0] <= 0.2) & (worst[:, 2] <= 1.5))
    t = np.median([s for _, _, s in rows])
    print(f"| {name} | {len(rows)} | {100 * ok_centre:.0f}% | {100 * ok_object:.0f}% | "
          f"{np.median(worst[:, 0]):.3f} / {np.percentile(worst[:, 0], 95):.3f} | "
          f"{np.median(worst[:, 1]):.2f} / {np.percentile(worst[:, 1], 95):.2f} | "
          f"{np.median(worst[:, 2]):.2f} / {np.percentile(worst[:, 2], 95):.2f} | {t:.2f} |")


def relative_errors(est, truth):
    """Rotation (deg) and translation (mm) error of every consecutive relative pose."""
    rot, trans = [], []
    for i in range(len(truth) - 1):
        g = np.linalg.inv(truth[i]) @ truth[i + 1]
        e = np.linalg.inv(est[i]) @ est[i + 1]
        d = np.linalg.inv(g) @ e
        rot.append(np.degrees(np.arccos(np.clip((np.trace(d[:3, :3]) - 1) / 2, -1, 1))))
        trans.append(1000 * np.linalg.norm(d[:3, 3]))
    return np.array(rot), np.array(trans)


def o3d_sequence(docs):
    """Open3D: consecutive point-to-plane ICP from the identity, pose graph with the closure."""
    reg = o3d.pipelines.registration
    clouds = [o3d_view_cloud(d, 0.005) for _, d in docs]
    n = len(clouds)
    graph = reg.PoseGraph()
    odometry = np.eye(4)
    graph.nodes.append(reg.PoseGraphNode(odometry))
    chained = [np.eye(4)]
    for i in range(n):
        j = (i + 1) % n  # source j onto target i
        t = o3d_p2plane(clouds[j], clouds[i], np.eye(4))
        info = reg.get_information_matrix_from_point_clouds(clouds[j], clouds[i], 0.012, t)
        if j != 0:
            chained.append(chained[-1] @ t)
            graph.nodes.append(reg.PoseGraphNode(chained[-1]))
        graph.edges.append(reg.PoseGraphEdge(j, i, t, info, uncertain=(j == 0)))
    loop = chained[-1] @ graph.edges[-1].transformation  # back at frame 0
    optimise(graph)
    return [np.asarray(nd.pose) for nd in graph.nodes], loop


def uva(b, work):
    root = os.path.join(DATA, "..", "multiview", "uva_cv2_person_kinect1")
    inp = os.path.join(work, "uva_in.ply")
    run(f"{b}/rgbd-cloud {root} -q > {inp}")
    docs = read_stream(inp)
    truth = [pose_of(c) for c, _ in docs]  # per-frame pseudo ground truth
    out = os.path.join(work, "uva_ours.ply")
    t0 = time.perf_counter()
    run(f"{b}/rgbd-align --ignore-poses -q --metrics {work}/uva_ours.json -o {out} < {inp}")
    t_ours = time.perf_counter() - t0
    est = [pose_of(c) for c, _ in read_stream(out)]
    loop = json.load(open(f"{work}/uva_ours.json"))["align"].get("loop_closure", {})
    t0 = time.perf_counter()
    o3d_poses, o3d_loop = o3d_sequence(docs)
    t_o3d = time.perf_counter() - t0
    print(f"\n### uva person, {len(docs)} frames, no initial poses: consecutive relative pose "
          "error against the pseudo ground truth")
    print("| method | rotation deg median / p90 | translation mm median / p90 | loop closure "
          "before (chained) | after | time s |")
    print("|---|---|---|---|---|---|")
    r, t = relative_errors(est, truth)
    print(f"| ours | {np.median(r):.3f} / {np.percentile(r, 90):.3f} | {np.median(t):.2f} / "
          f"{np.percentile(t, 90):.2f} | {loop.get('before_rotation_deg', float('nan')):.2f} deg"
          f" / {1000 * loop.get('before_translation_m', float('nan')):.1f} mm | "
          f"{loop.get('after_rotation_deg', float('nan')):.3f} deg / "
          f"{1000 * loop.get('after_translation_m', float('nan')):.2f} mm | {t_ours:.1f} |")
    r, t = relative_errors(o3d_poses, truth)
    lr = np.degrees(np.arccos(np.clip((np.trace(o3d_loop[:3, :3]) - 1) / 2, -1, 1)))
    print(f"| o3d-p2plane + pose graph | {np.median(r):.3f} / {np.percentile(r, 90):.3f} | "
          f"{np.median(t):.2f} / {np.percentile(t, 90):.2f} | {lr:.2f} deg / "
          f"{1000 * np.linalg.norm(o3d_loop[:3, 3]):.1f} mm | - | {t_o3d:.1f} |", flush=True)


def main():
    ap = argument_parser(__doc__)
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--calib-deg", type=float, default=5.0)
    ap.add_argument("--calib-mm", type=float, default=50.0)
    ap.add_argument("--busts", default="max_planck,bust_man_wreath")
    ap.add_argument("--no-peers", action="store_true", help="skip the Open3D runs")
    ap.add_argument("--uva", action="store_true", help="also the real person sequence")
    a = ap.parse_args()
    work = work_folder("measure_align", a.work, needs=DATA)
    b = os.path.abspath(a.bin)
    print(f"work dir {work}; calibration error {a.calib_deg} deg / {a.calib_mm} mm, "
          f"seeds {a.first_seed}..{a.first_seed + a.seeds - 1}")
    for bust in [x for x in a.busts.split(",") if x]:
        mesh, extra = BUSTS[bust]
        results = {"ours": [], "o3d-p2plane": [], "o3d-colored": []}
        for seed in range(a.first_seed, a.first_seed + a.seeds):
            cap = os.path.join(work, f"{bust}_{seed}")
            if not os.path.isdir(cap):
                run(f"{b}/rgbd-synth {os.path.join(DATA, mesh)} -o {cap} -q --seed {seed} "
                    f"--calib-error-deg {a.calib_deg} --calib-error-mm {a.calib_mm} "
                    + " ".join(extra))
            inp = cap + "_in.ply"
            run(f"{b}/rgbd-cloud {cap} | {b}/rgbd-clean --distance -q > {inp}")
            docs = read_stream(inp)
            truth_all = json.load(open(os.path.join(cap, "gt", "world_from_depth.json")))
            sensors = [meta(c, "view.sensor") for c, _ in docs]
            truth = {s: np.array(truth_all[s]) for s in sensors}
            rng = np.random.default_rng(0)
            pts = {}
            for s, (_, d) in zip(sensors, docs):
                xyz = xyz_of(d)
                pts[s] = xyz[rng.choice(len(xyz), min(3000, len(xyz)), replace=False)]

            out = cap + "_ours.ply"
            t0 = time.perf_counter()
            run(f"{b}/rgbd-align -q --seed {seed} --metrics {cap}_ours.json -o {out} < {inp}")
            t_ours = time.perf_counter() - t0
            est = {meta(c, "view.sensor"): pose_of(c) for c, _ in read_stream(out)}
            results["ours"].append((seed, pose_errors(est, truth, pts), t_ours))
            line = f"{bust} seed {seed}: ours {max(e[0] for e in results['ours'][-1][1].values()):.3f} deg"
            if not a.no_peers:
                for name, colored in (("o3d-p2plane", False), ("o3d-colored", True)):
                    t0 = time.perf_counter()
                    poses = o3d_ring(docs, colored)
                    dt = time.perf_counter() - t0
                    est = dict(zip(sensors, poses))
                    results[name].append((seed, pose_errors(est, truth, pts), dt))
                    line += f", {name} {max(e[0] for e in results[name][-1][1].values()):.3f} deg"
            print(line, flush=True)
        print(f"\n### {bust}: {a.seeds} seeds, calibration error {a.calib_deg} deg / {a.calib_mm} mm")
        print("| method | seeds | success (centre) | success (object) | worst rotation deg "
              "median / p95 | worst centre mm median / p95 | worst object mm median / p95 | "
              "time s (median) |")
        print("|---|---|---|---|---|---|---|---|")
        for name, rows in results.items():
            if rows:
                summarise(rows, name)
        print(flush=True)
    if a.uva:
        uva(b, work)


if __name__ == "__main__":
    main()
