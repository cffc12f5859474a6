#!/usr/bin/python3
"""Whole job on the real person against plain Open3D 0.16 pipelines, same frames, one run
(issues 18 and 38). Prints the time ratios (ours / Open3D-Poisson, ours / Open3D-TSDF), each
stage's time, peak memory, the consecutive-pair pose accuracy with both sides started alike and
a scaling table; writes the markdown to --out (validation/results/ by default, named with the
date and the commit).

Input: shared/data/multiview/uva_cv2_person_kinect1 (50 frames around 360 degrees, Kinect v1
class, 640 x 480 depth in mm registered to the colour JPEG, a subject mask per frame, per-frame
camera.xml poses good to a few tenths of a degree between neighbours).

Two runs, each side started alike in each (the results file says how, a line per run):
- TIMING run (the ratios): both sides start from the camera.xml poses, as a user who has them
  runs either tool.
  - ours: `rgbd-reconstruct CAP -o mesh.ply --frames SEL --report DIR --metrics m.json`, the
    default job (every stage on, with its report page; registration from the rig's poses),
    under /usr/bin/time -v (wall time, peak RSS); stage times and the aligned poses
    (align.views[].world_from_sensor) from metrics.json. No --stages-dir: writing every stage's
    stream is instrumentation a user's job does not pay for, and the Open3D side writes none.
  - Open3D registration (shared by both Open3D pipelines), on the views of
    `rgbd-cloud CAP --frames SEL` (sensor frames, the subject's masked pixels; rgbd-cloud not
    counted): per-frame statistical outlier removal (k 20, std 2), 2 mm voxels + normals (hybrid
    8 mm / 30, towards the camera); consecutive point-to-plane ICP, each pair (view j onto view
    i) started from the camera.xml relative pose inv(pose_i) @ pose_j (the views' rgbd:pose.
    world_from_sensor), multiscale 48/24/12/6 mm with 40/40/40/30 iterations, plus the
    loop-closing pair; pose graph with the camera.xml poses as its nodes (open3d_peer.optimise:
    Levenberg-Marquardt, edge prune 0.25, closing edge uncertain).
  - Open3D-Poisson: the registration, then merge (normals 10 mm / 30 towards each camera), 2 mm
    voxels, outlier removal; Screened Poisson depth 9, trimmed at the 2% density quantile.
  - Open3D-TSDF: the registration, then ScalableTSDFVolume (4 mm voxels, sdf_trunc 16 mm =
    4 voxels, colour RGB8) integrating every frame's depth PNG (mm) and colour JPEG, read from
    the capture with the frame's camera.xml intrinsics, the depth kept only inside the frame's
    _mask.jpg (>= 128, as rgbd-cloud reads it, so both sides fuse the subject's pixels), at the
    registered pose; extract_triangle_mesh (marching cubes).
  Each Open3D pipeline runs in its own child process under /usr/bin/time -v (wall, peak RSS).
  --repeat N (default 3) timing rounds, the three jobs in turn each round: the ratios use each
  side's median wall time, and every round's times are printed (a shared machine's slow minute
  then falls on every side alike).
- POSE-ACCURACY run: both sides start WITHOUT the poses. Ours: the pipe equivalent of the
  default job's stages up to the alignment, `rgbd-cloud CAP --frames SEL | rgbd-clean
  --distance | rgbd-align --ignore-poses --metrics m.json` (rgbd-reconstruct has no option to
  ignore the poses; `| rgbd-upsample` before rgbd-align only when the default job super-resolved
  views: it does not on the person's registered 640 x 480 frames, where the standalone tool
  would add points; align.views[].world_from_sensor, in the first view's frame); Open3D: the
  registration above with every pair started from the identity and the pose graph nodes
  chained from the pair results.
- Pose accuracy: rotation error of every consecutive pair's relative pose against camera.xml,
  median, p90 and max, for the pose-accuracy run and (as a check, figures that measure how far
  each side moved from its own start) the timing run; loop closure: the gap left at the
  closing pair after the pose graph (ours: metrics align.loop_closure when the metrics have it).
- Scaling (--scaling): ours and Open3D-Poisson (timing run) on 10, 25 and 50 frames spread over
  the whole turn (--frames 0:50:5, 0:50:2, 0:50); ours against points per view
  (--points-scaling): the pipe equivalent of the default job (rgbd-clean --distance |
  rgbd-align | rgbd-clean --density | rgbd-fill | rgbd-mesh --watertight) on the 50 frames with
  every view randomly thinned to 25%, 50% and 100% of its points.

The machine may be shared: the results file gives the load average at the start; the ratios,
measured in the same run, are what the benchmark compares.

Usage: person_vs_open3d.py [--bin build/bin] [--work DIR] [--out FILE] [--scaling]
                           [--points-scaling] [--frames 0:50]
"""
import argparse
import datetime
import json
import os
import re
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "quality", "common"))
from open3d_peer import (CRASH_RETRIES, merge_views, prepare_views, register_ring,  # noqa: E402
                         screened_poisson, tsdf_mesh)
from rgbd_stream import (argument_parser, meta, pose_of, read_stream, run_stamp,  # noqa: E402
                         work_folder)

PERSON = os.path.normpath(os.path.join(HERE, "..", "..", "..", "shared", "data", "multiview",
                                       "uva_cv2_person_kinect1"))


def sh(cmd):
    r = subprocess.run(cmd, shell=True, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"person_vs_open3d: failed: {cmd}\n{r.stderr[-2000:]}")
    return r


def timed(cmd, crash_retries=0):
    """Runs cmd (bash, pipefail: a pipe fails when any of its tools fails) under
    /usr/bin/time -v; returns (wall s, peak RSS MB, stdout). When a signal
    kills it (exit code 128 + SIGSEGV or SIGABRT: Open3D's Poisson race, Open3D issue 6828),
    runs it again up to crash_retries times, with a warning; the figures are the last run's."""
    for attempt in range(crash_retries + 1):
        r = subprocess.run(["/usr/bin/time", "-v", "bash", "-o", "pipefail", "-c", cmd],
                           capture_output=True, text=True)
        if r.returncode not in (139, 134) or attempt == crash_retries:
            break
        print(f"warning: killed by a signal (exit code {r.returncode}; Open3D's Poisson race, "
              f"Open3D issue 6828), running it again: {cmd}", file=sys.stderr, flush=True)
    if r.returncode != 0:
        sys.exit(f"person_vs_open3d: failed: {cmd}\n{r.stderr[-2000:]}")
    wall = re.search(r"Elapsed \(wall clock\) time.*: (?:(\d+):)?(\d+):([\d.]+)", r.stderr)
    h, m, s = wall.groups()
    seconds = (int(h) if h else 0) * 3600 + int(m) * 60 + float(s)
    rss = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", r.stderr).group(1))
    return seconds, rss / 1024.0, r.stdout


def rot_deg(r):
    return float(np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1))))


def pair_errors(est, truth):
    """Rotation error (degrees) of every consecutive relative pose against the truth."""
    return np.array([rot_deg((np.linalg.inv(np.linalg.inv(truth[i]) @ truth[i + 1]) @
                              (np.linalg.inv(est[i]) @ est[i + 1]))[:3, :3])
                     for i in range(len(truth) - 1)])


# --------------------------------------------------------------------------- Open3D (child)


def capture_frame(comments):
    """The capture images of one view of the UvA layout (docs/formats.md, foreign layouts):
    the depth PNG the view came from (rgbd:view.source; uint16 mm, registered to the colour
    image), the colour JPEG NNN.jpg beside it, the subject mask NNN_mask.jpg (kept >= 128, as
    the capture reader does) and the intrinsics of NNN_camera.xml (size from the depth image).
    Returns a frame dict of open3d_peer.tsdf_mesh with the depth zeroed outside the mask."""
    import open3d as o3d
    depth_path = meta(comments, "view.source")
    if depth_path is None or not depth_path.endswith("_depth.png"):
        sys.exit(f"person_vs_open3d: a view without a UvA depth image source ({depth_path})")
    stem = depth_path[:-len("_depth.png")]
    for f in (depth_path, stem + ".jpg", stem + "_camera.xml"):
        if not os.path.exists(f):
            sys.exit(f"person_vs_open3d: {f} not found (the TSDF pipeline reads the capture)")
    xml = open(stem + "_camera.xml").read()
    k = re.search(r"<intrinsic[^>]*>.*?<data>(.*?)</data>", xml, re.S)
    if k is None:
        sys.exit(f"person_vs_open3d: {stem}_camera.xml: no intrinsic matrix")
    k = [float(x) for x in k.group(1).split()]
    depth = np.asarray(o3d.io.read_image(depth_path)).copy()
    color = np.asarray(o3d.io.read_image(stem + ".jpg"))
    if os.path.exists(stem + "_mask.jpg"):
        mask = np.asarray(o3d.io.read_image(stem + "_mask.jpg"))
        depth[(mask if mask.ndim == 2 else mask[..., 0]) < 128] = 0
    h, w = depth.shape
    return {"color": color, "depth": depth, "depth_scale": 1000.0,
            "intrinsics": (w, h, k[0], k[4], k[2], k[5])}


def o3d_job(views_path, out_mesh, out_json, start, surface):
    """An Open3D pipeline on a sensor-frame view stream; writes stage times, poses and the loop
    gap to out_json. start: "poses" (pairs and graph nodes from the views' world_from_sensor)
    or "identity"; surface: "poisson", "tsdf" (from the capture images) or "none" (the
    registration alone)."""
    import open3d as o3d
    t = {}
    t0 = time.perf_counter()
    docs = read_stream(views_path)
    full, small = prepare_views([doc for _, doc in docs], 0.002)
    t["load_clean_s"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    n = len(docs)
    starts = [pose_of(c) for c, _ in docs] if start == "poses" else None
    if starts is not None and any(p is None for p in starts):
        sys.exit("person_vs_open3d: a view without rgbd:pose.world_from_sensor")
    poses, edges = register_ring(small, starts)
    t["registration_s"] = time.perf_counter() - t1  # pairwise ICP and the pose graph
    out = {"points": 0, "faces": 0}
    if surface == "poisson":
        t3 = time.perf_counter()
        merged = merge_views(full, poses)
        t["merge_s"] = time.perf_counter() - t3
        t4 = time.perf_counter()
        mesh, dens = screened_poisson(merged, 9)
        mesh.remove_vertices_by_mask(dens < np.quantile(dens, 0.02))
        t["poisson_s"] = time.perf_counter() - t4
        out["points"] = len(merged.points)
    elif surface == "tsdf":
        t3 = time.perf_counter()
        frames = [capture_frame(c) for c, _ in docs]
        t["read_images_s"] = time.perf_counter() - t3
        mesh, t["tsdf_integrate_s"], t["marching_cubes_s"] = tsdf_mesh(frames, poses)
    t["total_s"] = time.perf_counter() - t0
    if surface != "none":
        o3d.io.write_triangle_mesh(out_mesh, mesh)
        out["faces"] = len(mesh.triangles)
    # The gap left at the closing pair (source 0 onto target n-1) after the pose graph.
    gap = np.linalg.inv(edges[-1]) @ (np.linalg.inv(poses[-1]) @ poses[0]) if n > 2 else np.eye(4)
    out.update({"times": t, "poses": [p.tolist() for p in poses],
                "loop_after_deg": rot_deg(gap[:3, :3]),
                "loop_after_mm": 1000 * float(np.linalg.norm(gap[:3, 3]))})
    json.dump(out, open(out_json, "w"))


# --------------------------------------------------------------------------- runs


def find_key(x, key):
    """The first value of `key` in a nested JSON value, depth first, or None."""
    if isinstance(x, dict):
        if key in x:
            return x[key]
        x = list(x.values())
    if isinstance(x, list):
        for v in x:
            r = find_key(v, key)
            if r is not None:
                return r
    return None


def aligned_poses(align):
    """4x4 world_from_sensor of align.views[] of rgbd-align's metrics, in view order."""
    poses = []
    for v in sorted(align["views"], key=lambda v: v.get("view", 0)):
        pose = np.eye(4)
        pose[:3, :4] = np.array(v["world_from_sensor"], dtype=float).reshape(3, 4)
        poses.append(pose)
    return poses


def run_ours(b, frames, d, tag):
    """Timing run: the default job, registration from the camera.xml poses."""
    mesh, metrics = f"{d}/{tag}.ply", f"{d}/{tag}_m.json"
    wall, rss, _ = timed(f"{b}/rgbd-reconstruct {PERSON} -o {mesh} --frames {frames} -q "
                         f"--report {d}/{tag}_report --metrics {metrics}")
    m = json.load(open(metrics))
    rec = m.get("reconstruct", m)
    st = {s.get("name", s.get("stage", "?")): s.get("time_s", 0.0) for s in rec.get("stages", [])}
    upsampled = sum(s.get("views", 0) for s in rec.get("stages", [])
                    if s.get("stage") == "upsample")
    return {"wall_s": wall, "rss_mb": rss, "stages": st, "poses": aligned_poses(rec["align"]),
            "loop": find_key(m, "loop_closure") or {}, "upsampled_views": upsampled}


def no_poses_pipe(b, frames, upsample, metrics):
    """The default job's stages up to the alignment as a pipe, the alignment started without
    the poses. rgbd-upsample only when the default job ran it (`upsample`: rgbd-reconstruct
    super-resolves only views whose colour camera has more pixels than the depth camera, not
    the person's registered 640 x 480 frames; the standalone tool would add points)."""
    return (f"{b}/rgbd-cloud {PERSON} --frames {frames} -q | {b}/rgbd-clean --distance -q | " +
            (f"{b}/rgbd-upsample -q | " if upsample else "") +
            f"{b}/rgbd-align --ignore-poses -q --metrics {metrics}")


def run_ours_no_poses(b, frames, d, tag, upsample):
    """Pose-accuracy run: no_poses_pipe, timed; the aligned poses from its metrics."""
    metrics = f"{d}/{tag}_noposes_align.json"
    cmd = no_poses_pipe(b, frames, upsample, metrics)
    wall, rss, _ = timed(f"{cmd} > {d}/{tag}_noposes_aligned.ply")
    m = json.load(open(metrics))
    return {"wall_s": wall, "rss_mb": rss, "poses": aligned_poses(m.get("align", m)),
            "loop": find_key(m, "loop_closure") or {},
            "cmd": cmd.replace(b + "/", "").replace(metrics, "m.json").replace(PERSON, "CAP")}


def run_o3d(views, d, tag, start, surface):
    """One Open3D pipeline (o3d_job) in a child process under /usr/bin/time -v."""
    name = f"{d}/{tag}_o3d_{start}_{surface}"
    wall, rss, _ = timed(f"/usr/bin/python3 {os.path.abspath(__file__)} --o3d-child {views} "
                         f"{name}.ply {name}.json {start} {surface}",
                         crash_retries=CRASH_RETRIES)
    r = json.load(open(f"{name}.json"))
    return {"wall_s": wall, "rss_mb": rss, "times": r["times"], "faces": r["faces"],
            "poses": [np.array(p) for p in r["poses"]], "loop_after_deg": r["loop_after_deg"],
            "loop_after_mm": r["loop_after_mm"]}


def camera_views(b, frames, d, tag):
    """`rgbd-cloud CAP --frames SEL` into d/TAG_views.ply (not timed); returns (path, the
    camera.xml poses the views carry: world_from_sensor)."""
    views = f"{d}/{tag}_views.ply"
    sh(f"{b}/rgbd-cloud {PERSON} --frames {frames} -q > {views}")
    return views, [pose_of(c) for c, _ in read_stream(views)]


def thin_stream(src, dst, fraction, seed=1):
    """Copies a PLY view stream keeping a random `fraction` of every view's points."""
    data = open(src, "rb").read()
    rng = np.random.default_rng(seed)
    out, pos = [], 0
    while pos < len(data):
        end = data.index(b"end_header\n", pos) + len(b"end_header\n")
        header = data[pos:end].decode("ascii")
        count = int(re.search(r"element vertex (\d+)", header).group(1))
        doc = read_stream_header_size(header)
        body = np.frombuffer(data, dtype=doc, count=count, offset=end)
        keep = body[np.sort(rng.choice(count, int(round(count * fraction)), replace=False))]
        out.append(header.replace(f"element vertex {count}", f"element vertex {len(keep)}")
                   .encode("ascii") + keep.tobytes())
        pos = end + count * doc.itemsize
    open(dst, "wb").write(b"".join(out))


def read_stream_header_size(header):
    from rgbd_stream import PLY_TYPES
    fields, element = [], None
    for line in header.splitlines():
        p = line.split()
        if p and p[0] == "element":
            element = p[1]
        elif p and p[0] == "property" and element == "vertex":
            fields.append((p[-1], "<" + PLY_TYPES[p[1]]))
    return np.dtype(fields)


def pose_row(name, poses, truth, loop_deg, loop_mm):
    """A markdown row of the pose table: pair rotation error median / p90 / max, loop gap."""
    if len(poses) != len(truth):
        sys.exit(f"person_vs_open3d: {name}: {len(poses)} aligned poses for {len(truth)} views")
    e = pair_errors(poses, truth)
    loop = "n/a (not in the metrics)" if np.isnan(loop_deg) else \
        f"{loop_deg:.3f} deg / {loop_mm:.2f} mm"
    return (f"| {name} | {np.median(e):.3f} | {np.percentile(e, 90):.3f} | {e.max():.3f} | "
            f"{loop} |")


def ours_row(name, ours, truth):
    lp = ours["loop"]
    return pose_row(name, ours["poses"], truth, lp.get("after_rotation_deg", float("nan")),
                    1000 * lp.get("after_translation_m", float("nan")))


def o3d_row(name, o3d, truth):
    return pose_row(name, o3d["poses"], truth, o3d["loop_after_deg"], o3d["loop_after_mm"])


def stamp(what):
    print(f"[{datetime.datetime.now():%H:%M:%S}] {what}", file=sys.stderr, flush=True)


def main():
    ap = argument_parser(__doc__)
    ap.add_argument("--out", default=None, help="markdown file (default validation/results/"
                    "DATE-person-vs-open3d-COMMIT.md)")
    ap.add_argument("--frames", default="0:50", help="frame positions of the main comparison")
    ap.add_argument("--scaling", action="store_true", help="also 10 and 25 frames (0:50:5, 0:50:2)")
    ap.add_argument("--points-scaling", action="store_true",
                    help="also ours on views thinned to 25%% and 50%% of their points")
    ap.add_argument("--repeat", type=int, default=3,
                    help="timing rounds of the main comparison, each running ours, "
                    "Open3D-Poisson and Open3D-TSDF in turn; the table gives each side's median "
                    "wall time and the rounds' ratios (default 3)")
    ap.add_argument("--o3d-child", nargs=5, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.repeat < 1:
        sys.exit(f"person_vs_open3d: --repeat {a.repeat}: at least one round is needed")
    if a.o3d_child:
        o3d_job(*a.o3d_child)
        return
    b = os.path.abspath(a.bin)
    for tool in ("rgbd-reconstruct", "rgbd-cloud", "rgbd-clean", "rgbd-upsample", "rgbd-align"):
        if not os.path.exists(f"{b}/{tool}"):
            sys.exit(f"person_vs_open3d: {b}/{tool} not found (build first, or --bin)")
    work = work_folder("person_vs_open3d", a.work, needs=PERSON)
    today, commit = run_stamp(HERE)
    load = os.getloadavg()
    lines = [f"# Person: rgbd-reconstruct against Open3D 0.16 ({today})", "",
             f"- commit {commit}; machine: {os.cpu_count()} cores (nproc), shared with other "
             f"jobs: load average {load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f} (1 / 5 / 15 "
             "min) at the start; absolute times vary with the load, the ratios (both sides in "
             f"the same run) are what counts; work {work}",
             f"- command: `{' '.join(sys.argv)}`", ""]

    def say(s=""):
        print(s, flush=True)
        lines.append(s)

    sets = [(a.frames, "main")]
    if a.scaling:
        sets = [("0:50:5", "f10"), ("0:50:2", "f25")] + sets
    results = {}
    for frames, tag in sets:
        views, truth = camera_views(b, frames, work, tag)
        stamp(f"frames {frames}: ours, from the poses")
        ours = run_ours(b, frames, work, tag)
        stamp(f"frames {frames}: Open3D-Poisson, from the poses")
        poisson = run_o3d(views, work, tag, "poses", "poisson")
        results[tag] = (frames, truth, ours, poisson)
    frames, truth, ours, poisson = results["main"]
    views = f"{work}/main_views.ply"
    stamp(f"frames {frames}: Open3D-TSDF, from the poses")
    tsdf = run_o3d(views, work, "main", "poses", "tsdf")
    # More timing rounds, the three in turn, so that a slow minute of a shared machine falls
    # on every side alike; each side's median wall time goes to the table (the first round's
    # stages and poses are kept).
    rounds = [(ours["wall_s"], poisson["wall_s"], tsdf["wall_s"])]
    for r in range(1, a.repeat):
        stamp(f"frames {frames}: timing round {r + 1} of {a.repeat}")
        rounds.append((run_ours(b, frames, work, f"round{r}")["wall_s"],
                       run_o3d(views, work, f"round{r}", "poses", "poisson")["wall_s"],
                       run_o3d(views, work, f"round{r}", "poses", "tsdf")["wall_s"]))
    for side, col in ((ours, 0), (poisson, 1), (tsdf, 2)):
        side["wall_s"] = float(np.median([w[col] for w in rounds]))
    stamp(f"frames {frames}: ours, without the poses")
    ours_np = run_ours_no_poses(b, frames, work, "main", ours["upsampled_views"] > 0)
    stamp(f"frames {frames}: Open3D registration, from the identity")
    o3d_np = run_o3d(views, work, "main", "identity", "none")

    n = len(truth)
    say(f"## Timing run: whole job, frames {frames} ({n} views), both sides from the poses")
    say("")
    say("How each side started:")
    say("- ours: `rgbd-reconstruct` default job; registration from the camera.xml poses (the "
        "capture's per-frame world_from_depth).")
    say("- Open3D-Poisson and Open3D-TSDF: the same Open3D registration; each consecutive pair "
        "started from the camera.xml relative pose inv(pose_i) @ pose_j, the pose graph nodes "
        "at the camera.xml poses.")
    say("")
    say(f"Wall times: the median of {len(rounds)} round(s), ours, Open3D-Poisson and "
        "Open3D-TSDF in turn each round; the rounds (s): " +
        "; ".join(f"{o:.1f} / {p:.1f} / {t:.1f} (ratios {o / p:.2f}, {o / t:.2f})"
                  for o, p, t in rounds) + ". Peak RSS, mesh faces and stage times: the "
        "first round.")
    say("")
    say("| | wall s | peak RSS MB | mesh faces |")
    say("|---|---|---|---|")
    say(f"| ours (rgbd-reconstruct, default job) | {ours['wall_s']:.1f} | {ours['rss_mb']:.0f} "
        "| |")
    say(f"| Open3D-Poisson (registration, merge, Screened Poisson depth 9; rgbd-cloud not "
        f"counted) | {poisson['wall_s']:.1f} | {poisson['rss_mb']:.0f} | {poisson['faces']} |")
    say(f"| Open3D-TSDF (registration, ScalableTSDFVolume 4 mm of the masked depth images, "
        f"marching cubes; rgbd-cloud not counted) | {tsdf['wall_s']:.1f} | "
        f"{tsdf['rss_mb']:.0f} | {tsdf['faces']} |")
    say(f"| **ratio ours / Open3D-Poisson** | **{ours['wall_s'] / poisson['wall_s']:.2f}** | "
        f"{ours['rss_mb'] / poisson['rss_mb']:.2f} | |")
    say(f"| **ratio ours / Open3D-TSDF** | **{ours['wall_s'] / tsdf['wall_s']:.2f}** | "
        f"{ours['rss_mb'] / tsdf['rss_mb']:.2f} | |")
    say("")
    say("Stages, ours (metrics.json time_s): " +
        ", ".join(f"{k} {v:.1f} s" for k, v in ours["stages"].items()))
    for name, r in (("Open3D-Poisson", poisson), ("Open3D-TSDF", tsdf)):
        say(f"Stages, {name}: " + ", ".join(f"{k[:-2]} {v:.1f} s" for k, v in r["times"].items()))
    say("")
    say("## Pose accuracy: consecutive pairs against camera.xml (rotation error, degrees)")
    say("")
    say("Pose-accuracy run, both sides started WITHOUT the poses:")
    say(f"- ours: `{ours_np['cmd']}`, the default job's stages up to "
        "the alignment (rgbd-upsample only when the default job super-resolved views: "
        f"{ours['upsampled_views']} here), every view started from its own sensor frame "
        f"({ours_np['wall_s']:.1f} s, not part of the ratios).")
    say("- Open3D: the same registration with every pair started from the identity, the graph "
        f"nodes chained from the pair results ({o3d_np['wall_s']:.1f} s).")
    say("")
    say("| method | median | p90 | max | loop gap after the pose graph |")
    say("|---|---|---|---|---|")
    say(ours_row("ours, without the poses", ours_np, truth))
    say(o3d_row("Open3D, from the identity", o3d_np, truth))
    say("")
    say("Timing run, both sides from the poses (a check: the figures measure how far each side "
        "moved from the camera.xml poses it started from, which are also the truth):")
    say("")
    say("| method | median | p90 | max | loop gap after the pose graph |")
    say("|---|---|---|---|---|")
    say(ours_row("ours, from the poses", ours, truth))
    say(o3d_row("Open3D, from the poses", poisson, truth))
    say("")
    if a.scaling:
        say("## Scaling with the number of views (whole turn; timing run, from the poses)")
        say("")
        say("| frames | views | ours s | ours s / view | Open3D-Poisson s | ratio | ours peak MB |")
        say("|---|---|---|---|---|---|---|")
        for tag in ("f10", "f25", "main"):
            fr, tr, o, p = results[tag]
            nv = len(tr)
            say(f"| {fr} | {nv} | {o['wall_s']:.1f} | {o['wall_s'] / nv:.2f} | {p['wall_s']:.1f}"
                f" | {o['wall_s'] / p['wall_s']:.2f} | {o['rss_mb']:.0f} |")
        say("")
    if a.points_scaling:
        say(f"## Scaling with points per view (ours, pipe equivalent, frames {frames})")
        say("")
        say("| share of points | points per view (median) | wall s | align s | peak MB |")
        say("|---|---|---|---|---|")
        raw = f"{work}/main_views.ply"
        for frac in (0.25, 0.5, 1.0):
            thin = f"{work}/thin_{frac}.ply"
            thin_stream(raw, thin, frac)
            med = int(np.median([len(d) for _, d in read_stream(thin)]))
            m = f"{work}/thin_{frac}_align.json"
            pipe = (f"{b}/rgbd-clean --distance -q < {thin} | {b}/rgbd-align -q --metrics {m} | "
                    f"{b}/rgbd-clean --density -q | {b}/rgbd-fill -q | "
                    f"{b}/rgbd-mesh --watertight -q -o {work}/thin_{frac}.ply.mesh.ply")
            wall, rss, _ = timed(pipe)
            al = json.load(open(m))
            at = al.get("align", al).get("time_s", float("nan"))
            say(f"| {frac:.2f} | {med} | {wall:.1f} | {at:.1f} | {rss:.0f} |")
        say("")
    out = a.out or os.path.join(HERE, "..", "results", f"{today}-person-vs-open3d-{commit}.md")
    with open(out + ".tmp", "w") as f:
        f.write("\n".join(lines) + "\n")
    os.replace(out + ".tmp", out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
