#!/usr/bin/python3
"""Whole job on the real person against a plain Open3D 0.16 pipeline, same frames, one run
(issue 18). Prints the time ratio, each stage's time, peak memory, the consecutive-pair pose
accuracy and a scaling table; writes the markdown to --out (validation/results/ by default,
named with the date and the commit).

Input: shared/data/multiview/uva_cv2_person_kinect1 (50 frames around 360 degrees, Kinect v1
class, per-frame camera.xml poses good to a few tenths of a degree between neighbours).

- ours: `rgbd-reconstruct CAP -o mesh.ply --frames SEL --report DIR --metrics m.json`, the
  default job (every stage on, with its report page), under /usr/bin/time -v (wall time, peak
  RSS); stage times and the aligned poses (align.views[].world_from_sensor, the poses the
  aligned stream carries) from metrics.json. No --stages-dir: writing every stage's stream is
  instrumentation a user's job does not pay for, and the Open3D side writes none either.
- Open3D (the issue's pipeline), in a child process under /usr/bin/time -v, on the views of
  `rgbd-cloud CAP --frames SEL` (sensor frames; rgbd-cloud not counted): per-frame statistical
  outlier removal (k 20, std 2), 2 mm voxels + normals (hybrid 8 mm / 30, towards the camera);
  consecutive point-to-plane ICP from the identity, multiscale 48/24/12/6 mm with 40/40/40/30
  iterations, plus the loop-closing pair; pose graph (open3d_peer.optimise: Levenberg-Marquardt,
  edge prune 0.25, closing edge uncertain); merge (normals 10 mm / 30 towards each camera),
  2 mm voxels, outlier removal; Screened Poisson depth 9, trimmed at the 2% density quantile.
- Pose accuracy: rotation error of every consecutive pair's relative pose against camera.xml,
  median and p90; loop closure: the gap left at the closing pair after the pose graph (ours:
  metrics align.loop_closure).
- Scaling (--scaling): ours and Open3D on 10, 25 and 50 frames spread over the whole turn
  (--frames 0:50:5, 0:50:2, 0:50); ours against points per view (--points-scaling): the pipe
  equivalent of the default job (rgbd-clean --distance | rgbd-align | rgbd-clean --density |
  rgbd-fill | rgbd-mesh --watertight) on the 50 frames with every view randomly thinned to 25%,
  50% and 100% of its points.

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
from open3d_peer import (CRASH_RETRIES, merge_views, optimise, pair_icp, prepare_views,  # noqa: E402
                         screened_poisson)
from rgbd_stream import argument_parser, pose_of, read_stream, run_stamp, work_folder  # noqa: E402

PERSON = os.path.normpath(os.path.join(HERE, "..", "..", "..", "shared", "data", "multiview",
                                       "uva_cv2_person_kinect1"))


def sh(cmd):
    r = subprocess.run(cmd, shell=True, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"person_vs_open3d: failed: {cmd}\n{r.stderr[-2000:]}")
    return r


def timed(cmd, crash_retries=0):
    """Runs cmd under /usr/bin/time -v; returns (wall s, peak RSS MB, stdout). When a signal
    kills it (exit code 128 + SIGSEGV or SIGABRT: Open3D's Poisson race, Open3D issue 6828),
    runs it again up to crash_retries times, with a warning; the figures are the last run's."""
    for attempt in range(crash_retries + 1):
        r = subprocess.run(["/usr/bin/time", "-v", "sh", "-c", cmd], capture_output=True,
                           text=True)
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


def o3d_job(views_path, out_mesh, out_json):
    """The issue's Open3D pipeline; writes stage times and poses to out_json."""
    import open3d as o3d
    reg = o3d.pipelines.registration
    t = {}
    t0 = time.perf_counter()
    docs = read_stream(views_path)
    full, small = prepare_views([doc for _, doc in docs], 0.002)
    t["load_clean_s"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    n = len(docs)
    graph = reg.PoseGraph()
    chained = [np.eye(4)]
    graph.nodes.append(reg.PoseGraphNode(np.eye(4)))
    edges = []
    for i in range(n if n > 2 else n - 1):
        j = (i + 1) % n  # source j onto target i, from the identity
        tr, info = pair_icp(small, i, j, np.eye(4))
        if j != 0:
            chained.append(chained[-1] @ tr)
            graph.nodes.append(reg.PoseGraphNode(chained[-1]))
        graph.edges.append(reg.PoseGraphEdge(j, i, tr, info, uncertain=(j == 0)))
        edges.append(tr)
    t["pairwise_icp_s"] = time.perf_counter() - t1
    t2 = time.perf_counter()
    optimise(graph)
    poses = [np.asarray(node.pose) for node in graph.nodes]
    t["pose_graph_s"] = time.perf_counter() - t2
    t3 = time.perf_counter()
    merged = merge_views(full, poses)
    t["merge_s"] = time.perf_counter() - t3
    t4 = time.perf_counter()
    mesh, dens = screened_poisson(merged, 9)
    mesh.remove_vertices_by_mask(dens < np.quantile(dens, 0.02))
    t["poisson_s"] = time.perf_counter() - t4
    t["total_s"] = time.perf_counter() - t0
    o3d.io.write_triangle_mesh(out_mesh, mesh)
    # The gap left at the closing pair (source 0 onto target n-1) after the pose graph.
    gap = np.linalg.inv(edges[-1]) @ (np.linalg.inv(poses[-1]) @ poses[0]) if n > 2 else np.eye(4)
    json.dump({"times": t, "poses": [p.tolist() for p in poses], "points": len(merged.points),
               "loop_after_deg": rot_deg(gap[:3, :3]),
               "loop_after_mm": 1000 * float(np.linalg.norm(gap[:3, 3]))},
              open(out_json, "w"))


# --------------------------------------------------------------------------- runs


def run_ours(b, frames, d, tag):
    mesh, metrics = f"{d}/{tag}.ply", f"{d}/{tag}_m.json"
    wall, rss, _ = timed(f"{b}/rgbd-reconstruct {PERSON} -o {mesh} --frames {frames} -q "
                         f"--report {d}/{tag}_report --metrics {metrics}")
    m = json.load(open(metrics))
    rec = m.get("reconstruct", m)
    st = {s.get("name", s.get("stage", "?")): s.get("time_s", 0.0) for s in rec.get("stages", [])}
    poses = []
    for v in rec["align"]["views"]:
        pose = np.eye(4)
        pose[:3, :4] = np.array(v["world_from_sensor"], dtype=float).reshape(3, 4)
        poses.append(pose)
    loop = {}
    for key in ("align",):
        node = m.get(key) or rec.get(key) or {}
        for s in rec.get("stages", []):
            if s.get("name") == "align" and isinstance(s.get("report"), dict):
                node = s["report"]
        loop = node.get("loop_closure", loop)
    if not loop:  # search the metrics for the first loop_closure object
        def find(x):
            if isinstance(x, dict):
                if "loop_closure" in x:
                    return x["loop_closure"]
                for v in x.values():
                    r = find(v)
                    if r:
                        return r
            elif isinstance(x, list):
                for v in x:
                    r = find(v)
                    if r:
                        return r
            return None
        loop = find(m) or {}
    return {"wall_s": wall, "rss_mb": rss, "stages": st, "poses": poses, "loop": loop}


def run_o3d(b, frames, d, tag):
    views = f"{d}/{tag}_views.ply"
    sh(f"{b}/rgbd-cloud {PERSON} --frames {frames} -q > {views}")
    out = f"{d}/{tag}_o3d.json"
    wall, rss, _ = timed(f"/usr/bin/python3 {os.path.abspath(__file__)} --o3d-child {views} "
                         f"{d}/{tag}_o3d.ply {out}", crash_retries=CRASH_RETRIES)
    r = json.load(open(out))
    truth = [pose_of(c) for c, _ in read_stream(views)]
    return {"wall_s": wall, "rss_mb": rss, "times": r["times"],
            "poses": [np.array(p) for p in r["poses"]], "truth": truth,
            "loop_after_deg": r["loop_after_deg"], "loop_after_mm": r["loop_after_mm"]}


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


def main():
    ap = argument_parser(__doc__)
    ap.add_argument("--out", default=None, help="markdown file (default validation/results/"
                    "DATE-person-vs-open3d-COMMIT.md)")
    ap.add_argument("--frames", default="0:50", help="frame positions of the main comparison")
    ap.add_argument("--scaling", action="store_true", help="also 10 and 25 frames (0:50:5, 0:50:2)")
    ap.add_argument("--points-scaling", action="store_true",
                    help="also ours on views thinned to 25%% and 50%% of their points")
    ap.add_argument("--o3d-child", nargs=3, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.o3d_child:
        o3d_job(*a.o3d_child)
        return
    b = os.path.abspath(a.bin)
    if not os.path.exists(f"{b}/rgbd-reconstruct"):
        sys.exit(f"person_vs_open3d: {b}/rgbd-reconstruct not found (build first, or --bin)")
    work = work_folder("person_vs_open3d", a.work, needs=PERSON)
    today, commit = run_stamp(HERE)
    lines = [f"# Person: rgbd-reconstruct against Open3D 0.16 ({today})", "",
             f"- commit {commit}; machine: {os.cpu_count()} cores (nproc), shared; work {work}",
             f"- command: `{' '.join(sys.argv)}`", ""]

    def say(s=""):
        print(s, flush=True)
        lines.append(s)

    sets = [(a.frames, "main")]
    if a.scaling:
        sets = [("0:50:5", "f10"), ("0:50:2", "f25")] + sets
    results = {}
    for frames, tag in sets:
        print(f"[{datetime.datetime.now():%H:%M:%S}] frames {frames}: ours", file=sys.stderr,
              flush=True)
        ours = run_ours(b, frames, work, tag)
        print(f"[{datetime.datetime.now():%H:%M:%S}] frames {frames}: Open3D", file=sys.stderr,
              flush=True)
        o3d = run_o3d(b, frames, work, tag)
        results[tag] = (frames, ours, o3d)

    frames, ours, o3d = results["main"]
    n = len(o3d["truth"])
    say(f"## Whole job, frames {frames} ({n} views)")
    say("")
    say("| | wall s | peak RSS MB |")
    say("|---|---|---|")
    say(f"| ours (rgbd-reconstruct, default job) | {ours['wall_s']:.1f} | {ours['rss_mb']:.0f} |")
    say(f"| Open3D pipeline (rgbd-cloud not counted) | {o3d['wall_s']:.1f} | "
        f"{o3d['rss_mb']:.0f} |")
    say(f"| **ratio ours / Open3D** | **{ours['wall_s'] / o3d['wall_s']:.2f}** | "
        f"{ours['rss_mb'] / o3d['rss_mb']:.2f} |")
    say("")
    say("Stages, ours (metrics.json time_s): " +
        ", ".join(f"{k} {v:.1f} s" for k, v in ours["stages"].items()))
    say("Stages, Open3D: " + ", ".join(f"{k[:-2]} {v:.1f} s" for k, v in o3d["times"].items()))
    say("")
    truth = o3d["truth"]
    say("## Pose accuracy: consecutive pairs against camera.xml (rotation error, degrees)")
    say("")
    say("| method | median | p90 | max | loop gap after the pose graph |")
    say("|---|---|---|---|---|")
    e = pair_errors(ours["poses"], truth)
    lp = ours["loop"]
    say(f"| ours | {np.median(e):.3f} | {np.percentile(e, 90):.3f} | {e.max():.3f} | "
        f"{lp.get('after_rotation_deg', float('nan')):.3f} deg / "
        f"{1000 * lp.get('after_translation_m', float('nan')):.2f} mm |")
    e = pair_errors(o3d["poses"], truth)
    say(f"| Open3D | {np.median(e):.3f} | {np.percentile(e, 90):.3f} | {e.max():.3f} | "
        f"{o3d['loop_after_deg']:.3f} deg / {o3d['loop_after_mm']:.2f} mm |")
    say("")
    if a.scaling:
        say("## Scaling with the number of views (whole turn)")
        say("")
        say("| frames | views | ours s | ours s / view | Open3D s | ratio | ours peak MB |")
        say("|---|---|---|---|---|---|---|")
        for tag in ("f10", "f25", "main"):
            fr, o, p = results[tag]
            nv = len(p["truth"])
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
