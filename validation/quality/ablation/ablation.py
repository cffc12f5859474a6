#!/usr/bin/python3
"""Ablation benchmark of rgbd-reconstruct's stages against Open3D Screened Poisson (issue 17):
one command, one markdown table.

Objects (--objects):
- bunny: CGAL's demo bunny (libcgal-dev's data.tar.gz, data/meshes/bunny00.off), rendered by
  rgbd-synth as an 8-Kinect-v2 ring: --height-m 0.45 --up y;
- max_planck, bust_man_wreath: the busts of ../common/rgbd_stream.py (BUSTS, their rgbd-synth
  arguments);
  all with rgbd-synth's default noise and rig.json poses off by 1.5 deg / 15 mm, --seed;
- the variety set (--objects-dir DIR made by validation/quality/variety/objects.py --out DIR,
  or --variety: made in WORK/objects): busts, standing figures, animals, a seated cellist on a
  chair on the floor, a jug with a thin handle, a puppet on the SR300 turntable rig; each with
  its own rgbd-synth arguments from DIR/objects.json, its scene options (--floor ...) only when
  rgbd-synth lists them; --objects then names any of them (default: all of the set);
  --scene "--scene room" renders every ring object of the set in a room instead (floor, 2 walls,
  4 clutter objects, a person: validation/results/2026-12-07-bases-on-the-floor.md);
- person: the real sequence shared/data/multiview/uva_cv2_person_kinect1 (Kinect v1 class,
  per-frame camera.xml poses, no true surface), frames --person-frames (positions A:B).

Variants (--variants):
- default: rgbd-reconstruct CAP -o mesh.ply --report DIR --metrics m.json, i.e.
  cloud -> clean --distance -> upsample (8 neighbours; only when the colour camera has more
  pixels than the depth camera) -> align -> clean --density -> fill -> mesh --watertight;
- skip-distance, skip-upsample, skip-density, skip-fill: the same with --skip STAGE (on the
  person, skip-upsample is the default's run: Kinect v1 colour has the depth's pixel count, so
  upsampling never runs);
- o3d-spr, o3d-spr-trim: the Open3D 0.16 peer pipeline of docs/method.md on the views of rgbd-cloud: per-view
  statistical outlier removal (k 20, std 2), 5 mm voxels + normals for point-to-plane ICP
  between neighbouring views (48/24/12/6 mm, 40/40/40/30 iterations) from the rig's
  (camera.xml) poses, Open3D pose graph (Levenberg-Marquardt, closing edge uncertain), merge of
  the full clouds with normals (hybrid 10 mm / 30, towards each view's camera), 2 mm voxels,
  post outlier removal (k 20, std 2), Screened Poisson depth 9 (scale 1.1, width 0), untrimmed
  and trimmed at the 2% density quantile. Time: the whole Open3D pipeline from the loaded
  views (rgbd-cloud not counted). It runs in a child process, again when Open3D's Poisson race
  kills it (open3d_peer.run_in_child).
When the rgbd-reconstruct in --bin has no --skip (older builds), --chain pipe (the default
--chain auto falls back to it) runs the equivalent pipe
    rgbd-cloud | rgbd-clean --distance | rgbd-upsample --neighbors 8 | rgbd-align |
    rgbd-clean --density | rgbd-fill | rgbd-mesh --watertight -o mesh.ply
with the skipped stage left out (rgbd-upsample only on the Kinect v2 rings); time = its wall
time. With rgbd-reconstruct, time = the sum of reconstruct.stages time_s (no I/O, no
evaluation, no report pictures; the wall time of the process is in the JSON beside the table).

Scoring: every mesh, ours and Open3D's, by the same scorer,
    rgbd-eval MESH --reference CAP/gt/mesh.ply --tau-mm 1,2,5
F-score at 1/2/5 mm, invented surface (share of the mesh's area farther than 5 mm from the
truth), completeness mean (truth -> mesh, mm), accuracy mean (mesh -> truth, mm) and
rgbd-eval's mesh_quality (sliver_fraction_5deg: faces with a minimum angle < 5 deg; fold
edges; spike vertices). The person has no truth: time, mesh_quality against the aligned input
points (rgbd-eval MESH --points ALIGNED: far area > 3 mm, grey fill vertices) and the rotation
error of consecutive views' relative poses against camera.xml (median, p90; ours = rgbd-align
on the default chain's cleaned views, Open3D = its pose graph).

Seeds (--seeds 1,2,3): every synthetic ring is rendered and run once per seed (noise and rig
error drawn anew); the table shows the mean over the seeds first, then every run.

Verdict per object and stage, on the paired differences default - skip-STAGE over the seeds:
"earns its place" when F@2mm and completeness are no worse and invented surface no higher on
the mean; "no measurable harm" when one is worse on the mean by less than twice the standard
error of the paired difference (the seeds' spread); "HURTS" beyond it. "Measurably better"
lists the measures (those three, F@1mm, accuracy) the stage improves beyond twice the standard
error, with the number of seeds on which it did: what the stage is there for. On the busts, the
issue's targets on every seed: F@2mm >= 0.96, invented <= 0.5%, completeness <= 1.0 mm (also on
the set's objects of kind bust); on every object with truth, the fill stage's own points
farther than 5 mm from the truth <= 2%. A per-object summary table lists F@2mm / invented /
completeness of every variant, the fill share and the targets.
"""
import argparse
import datetime
import json
import os
import shlex
import subprocess
import sys
import tarfile
import tempfile
import time

import numpy as np

# Open3D's OpenMP workers spin while they wait by default: many times slower on a shared machine.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "common"))
sys.path.insert(0, os.path.join(HERE, "..", "variety"))
import objects as variety  # noqa: E402
from open3d_peer import (merge_views, optimise, pair_icp, prepare_views, run_in_child,  # noqa: E402
                         screened_poisson)
from rgbd_stream import BUSTS, DATA, pose_of, read_stream  # noqa: E402

PERSON = os.path.normpath(os.path.join(DATA, "..", "multiview", "uva_cv2_person_kinect1"))
CGAL_DATA = "/usr/share/doc/libcgal-dev/data.tar.gz"
STAGES = ["distance", "upsample", "density", "fill"]
ALL_VARIANTS = ["default"] + [f"skip-{s}" for s in STAGES] + ["o3d-spr", "o3d-spr-trim"]
BUSTS_WITH_TARGETS = ("max_planck", "bust_man_wreath")
FILL_FAR_TARGET = 0.02  # every object: the fill stage's points farther than 5 mm from the truth
OBJSET = {}  # name -> objects.json entry of --objects-dir / --variety (with "path")


def sh(cmd, log=None):
    """Runs a shell command (bash, pipefail); exits with its stderr on failure."""
    r = subprocess.run(["bash", "-o", "pipefail", "-c", cmd], capture_output=True, text=True)
    if log:
        with open(log, "a") as f:
            f.write(f"$ {cmd}\n{r.stderr}\n")
    if r.returncode != 0:
        sys.exit(f"ablation: failed ({r.returncode}): {cmd}\n{r.stderr[-4000:]}")
    return r.stdout


def has_skip(b):
    r = subprocess.run([f"{b}/rgbd-reconstruct", "--help"], capture_output=True, text=True)
    return "--skip" in r.stdout + r.stderr


# --------------------------------------------------------------------------- captures


def synth_options(b):
    """The option names the rgbd-synth in `b` lists in its --help."""
    r = subprocess.run([f"{b}/rgbd-synth", "--help"], capture_output=True, text=True)
    return {w.rstrip(",=") for w in (r.stdout + r.stderr).split() if w.startswith("--")}


def set_arguments(entry, b):
    """rgbd-synth arguments of an object of the set: its own, plus its scene options when the
    rgbd-synth in `b` has them (older builds render the object alone)."""
    scene = entry.get("scene") or []
    known = synth_options(b)
    if scene and all(x in known for x in scene if x.startswith("--")):
        return entry["synth"] + scene
    return entry["synth"]


def make_capture(obj, b, work, seed):
    """Capture folder of a synthetic object (rendered once per work dir and seed)."""
    cap = os.path.join(work, f"{obj}_s{seed}", "cap")
    if os.path.isdir(os.path.join(cap, "gt")):
        return cap
    os.makedirs(os.path.dirname(cap), exist_ok=True)
    if obj in OBJSET:
        mesh, extra = OBJSET[obj]["path"], set_arguments(OBJSET[obj], b)
        with open(os.path.join(work, f"{obj}_s{seed}", "synth_args.txt"), "w") as f:
            f.write(" ".join(extra) + "\n")
    elif obj == "bunny":
        mesh = os.path.join(work, "bunny00.off")
        if not os.path.exists(mesh):
            with tarfile.open(CGAL_DATA) as t:
                member = t.getmember("data/meshes/bunny00.off")
                with open(mesh, "wb") as f:
                    f.write(t.extractfile(member).read())
        extra = ["--height-m", "0.45", "--up", "y"]
    else:
        rel, extra = BUSTS[obj]
        mesh = os.path.join(DATA, rel)
    sh(f"{b}/rgbd-synth {shlex.quote(mesh)} -o {cap} -q --seed {seed} " + " ".join(extra))
    return cap


# --------------------------------------------------------------------------- our chain


def ours(obj, variant, cap, b, d, chain, frames, seed):
    """Runs our chain (default or --skip STAGE); returns (mesh path, time_s, info dict)."""
    skip = variant[len("skip-"):] if variant.startswith("skip-") else None
    mesh = os.path.join(d, f"{variant}.ply")
    info = {}
    log = os.path.join(d, f"{variant}.log")
    if chain == "reconstruct":
        metrics = os.path.join(d, f"{variant}_m.json")
        opts = f" --skip {skip}" if skip else ""
        if frames:
            opts += f" --frames {frames}"
        t0 = time.perf_counter()
        if variant == "default":  # its aligned views give the person's poses
            opts += f" --stages-dir {d}/{variant}_stages"
        sh(f"{b}/rgbd-reconstruct {cap} -o {mesh} --report {d}/{variant}_report "
           f"--metrics {metrics} --seed {seed} -q{opts}", log)
        wall = time.perf_counter() - t0
        m = json.load(open(metrics))
        rec = m.get("reconstruct", m)
        stages = rec.get("stages") or []
        info = {"wall_s": wall, "stages": stages}
        t = sum(s.get("time_s", 0.0) for s in stages) if stages else wall
        return mesh, t, info
    # The equivalent pipe.
    upsample = obj != "person"  # Kinect v1: colour and depth have the same pixel count
    parts = [f"{b}/rgbd-cloud {cap} -q" + (f" --frames {frames}" if frames else "")]
    if skip != "distance":
        parts.append(f"{b}/rgbd-clean --distance -q")
    if upsample and skip != "upsample":
        parts.append(f"{b}/rgbd-upsample --neighbors 8 --capture {cap} -q")
    parts.append(f"{b}/rgbd-align -q --seed {seed}")
    if skip != "density":
        parts.append(f"{b}/rgbd-clean --density -q")
    if skip != "fill":
        parts.append(f"{b}/rgbd-fill -q")
    parts.append(f"{b}/rgbd-mesh --watertight -q -o {mesh}")
    t0 = time.perf_counter()
    sh(" | ".join(parts), log)
    t = time.perf_counter() - t0
    return mesh, t, {"wall_s": t, "chain": " | ".join(parts)}


# --------------------------------------------------------------------------- Open3D peer


def o3d_pipeline(views, out_untrimmed, out_trimmed, depth=9, trim=0.02):
    """The Open3D peer pipeline (docs/method.md) on sensor-frame views [(comments, records)]; returns
    (seconds, world_from_sensor poses after the pose graph)."""
    import open3d as o3d
    reg = o3d.pipelines.registration
    t0 = time.perf_counter()
    full, small = prepare_views([doc for _, doc in views], 0.005)
    init = [p if p is not None else np.eye(4) for p in (pose_of(c) for c, _ in views)]
    n = len(views)
    graph = reg.PoseGraph()
    for p in init:
        graph.nodes.append(reg.PoseGraphNode(p))
    edges = range(n) if n > 2 else range(n - 1)
    for i in edges:
        j = (i + 1) % n  # source j onto target i; the closing edge (j = 0) is uncertain
        t, info = pair_icp(small, i, j, np.linalg.inv(init[i]) @ init[j])
        graph.edges.append(reg.PoseGraphEdge(j, i, t, info, uncertain=(j == 0)))
    optimise(graph)
    poses = [np.asarray(node.pose) for node in graph.nodes]
    mesh, dens = screened_poisson(merge_views(full, poses), depth)
    seconds = time.perf_counter() - t0
    o3d.io.write_triangle_mesh(out_untrimmed, mesh)
    mesh.remove_vertices_by_mask(dens < np.quantile(dens, trim))
    o3d.io.write_triangle_mesh(out_trimmed, mesh)
    return seconds, poses


# --------------------------------------------------------------------------- scoring


def evaluate(eb, mesh, reference=None, points=None, seed=1):
    cmd = f"{eb}/rgbd-eval {mesh} -q --seed {seed}"
    if reference:
        cmd += f" --reference {reference} --tau-mm 1,2,5"
    if points:
        cmd += f" --points {points}"
    return json.loads(sh(cmd))


def relative_rotation_errors(est, truth):
    """Rotation error (degrees) of every consecutive relative pose against the truth."""
    out = []
    for i in range(len(truth) - 1):
        g = np.linalg.inv(truth[i]) @ truth[i + 1]
        e = np.linalg.inv(est[i]) @ est[i + 1]
        r = (np.linalg.inv(g) @ e)[:3, :3]
        out.append(np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1))))
    return np.array(out)


def fmt(x, spec):
    return "-" if x is None else format(x, spec)


# --------------------------------------------------------------------------- main


FILL_GROUPS = [("small holes", (1, 2, 3, 4)), ("large holes", (5,)), ("head top", (6,))]


def fill_points(stream, reference):
    """The fill stage's added points (the documents with fill_mechanism) against the true
    surface: per mechanism group, count, largest distance (mm) and the shares farther than 3
    and 5 mm (Open3D RaycastingScene distances, degenerate triangles dropped)."""
    import open3d as o3d
    pts, mech = [], []
    for _, v in read_stream(stream):
        if v.dtype.names and "fill_mechanism" in v.dtype.names:
            pts.append(np.stack([v["x"], v["y"], v["z"]], 1).astype(np.float64))
            mech.append(v["fill_mechanism"])
    if not pts:
        return {}
    pts, mech = np.concatenate(pts), np.concatenate(mech)
    gt = o3d.io.read_triangle_mesh(reference)
    gt.remove_degenerate_triangles()
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(gt))
    dist = scene.compute_distance(o3d.core.Tensor(pts.astype(np.float32))).numpy()
    out = {}
    for name, ks in FILL_GROUPS + [("all", tuple(range(1, 256)))]:
        sel = np.isin(mech, ks)
        if sel.any():
            d = dist[sel]
            out[name] = {"points": int(sel.sum()), "max_mm": float(1000 * d.max()),
                         "over3": float((d > 0.003).mean()), "over5": float((d > 0.005).mean())}
    return out


def run_object(obj, a, b, eb, chain, rows, extra, seed):
    d = os.path.join(a.work, f"{obj}_s{seed}")
    os.makedirs(d, exist_ok=True)
    person = obj == "person"
    frames = a.person_frames if person else None
    if person:
        cap, reference = PERSON, None
    else:
        cap = make_capture(obj, b, a.work, seed)
        reference = os.path.join(cap, "gt", "mesh.ply")
    variants = [v for v in a.variants if v in ALL_VARIANTS]
    views = aligned = None
    pose_err = {}
    need_views = person or any(v.startswith("o3d") for v in variants)
    if need_views:
        raw = os.path.join(d, "views.ply")
        sh(f"{b}/rgbd-cloud {cap} -q" + (f" --frames {frames}" if frames else "") + f" > {raw}")
        views = read_stream(raw)
    o3d_done, ran = {}, {}
    if person:
        # Our poses and the input of the mesh quality measure: with rgbd-reconstruct, the
        # default job's own aligned views (--stages-dir: 02-align, and 03-density = the
        # measured points the mesher gets); else the default chain's aligned points (Kinect v1:
        # no upsampling) from a separate run.
        st = os.path.join(d, "default_stages")
        if chain == "reconstruct" and "default" in variants:
            print(f"[{datetime.datetime.now():%H:%M:%S}] {obj}: default", file=sys.stderr,
                  flush=True)
            ran["default"] = ours(obj, "default", cap, b, d, chain, frames, seed)
            posed = os.path.join(st, "02-align.ply")
            aligned = os.path.join(st, "03-density.ply")
            if not os.path.exists(aligned):
                aligned = posed
        else:
            aligned = posed = os.path.join(d, "aligned.ply")
            sh(f"{b}/rgbd-clean --distance -q < {raw} | {b}/rgbd-align -q --seed {seed} "
               f"> {aligned}")
        truth = [pose_of(c) for c, _ in views]
        est = [pose_of(c) for c, _ in read_stream(posed)]
        if len(est) == len(truth) and all(p is not None for p in truth + est):
            pose_err["ours"] = relative_rotation_errors(est, truth)
    for v in variants:
        if v not in ran:
            print(f"[{datetime.datetime.now():%H:%M:%S}] {obj}: {v}", file=sys.stderr,
                  flush=True)
        if v in ran:
            mesh, t, info = ran[v]
        elif v.startswith("o3d"):
            if not o3d_done:
                u, tr = os.path.join(d, "o3d-spr.ply"), os.path.join(d, "o3d-spr-trim.ply")
                secs, poses = run_in_child(o3d_pipeline, views, u, tr, what=f"{obj}: Open3D")
                o3d_done = {"o3d-spr": u, "o3d-spr-trim": tr, "time": secs}
                if person:
                    pose_err["o3d"] = relative_rotation_errors(poses, truth)
            mesh, t, info = o3d_done[v], o3d_done["time"], {}
        elif person and v == "skip-upsample" and "default" in ran:
            # Kinect v1: colour and depth have the same pixel count, upsampling never runs.
            mesh, t, info = ran["default"]
            info = dict(info, note="same as default: no upsampling on Kinect v1 data")
        else:
            mesh, t, info = ours(obj, v, cap, b, d, chain, frames, seed)
            ran[v] = (mesh, t, info)
        e = evaluate(eb, mesh, reference, aligned, seed)
        s = e.get("surface", {})
        q = e.get("mesh_quality", {})
        pe = pose_err.get("o3d" if v.startswith("o3d") else "ours") if person else None
        if person and v.startswith("skip-") and v in ("skip-distance",):
            pe = None  # its alignment differs from the default's; not measured separately
        row = {
            "object": obj, "variant": v, "seed": seed, "time_s": t,
            "f1": s.get("fscore_1mm"), "f2": s.get("fscore_2mm"), "f5": s.get("fscore_5mm"),
            "invented": s.get("invented_surface_fraction"),
            "completeness_mm": 1000 * s["completeness_mean_m"] if s else None,
            "accuracy_mm": 1000 * s["accuracy_mean_m"] if s else None,
            "sliver5": q.get("sliver_fraction_5deg"), "folds": q.get("fold_edge_fraction"),
            "spikes": q.get("spike_vertex_fraction"), "far3": q.get("far_area_fraction_3mm"),
            "grey": q.get("grey_vertex_fraction"),
            "pose_med": float(np.median(pe)) if pe is not None and len(pe) else None,
            "pose_p90": float(np.percentile(pe, 90)) if pe is not None and len(pe) else None,
        }
        if v == "default" and reference:
            stream = os.path.join(d, "default_stages", "04-fill.ply")
            if os.path.exists(stream):
                row["fill_points"] = fill_points(stream, reference)
        rows.append(row)
        extra.append({"object": obj, "variant": v, "seed": seed, "mesh": mesh, "info": info, "eval": e})
        print(table_row(row), file=sys.stderr, flush=True)


HEADER = ("| object | variant | seed | F@1mm | F@2mm | F@5mm | invented >5mm | completeness mean mm | "
          "accuracy mean mm | sliver_fraction_5deg | time s | fold edges | spike vertices | "
          "far >3mm (person) | grey (person) | pose rot err deg med / p90 (person) |\n"
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")


def table_row(r):
    pose = "-" if r["pose_med"] is None else f"{r['pose_med']:.3f} / {r['pose_p90']:.3f}"
    inv = "-" if r["invented"] is None else f"{100 * r['invented']:.2f}%"
    return (f"| {r['object']} | {r['variant']} | {r['seed']} | {fmt(r['f1'], '.3f')} | {fmt(r['f2'], '.3f')} | "
            f"{fmt(r['f5'], '.3f')} | {inv} | {fmt(r['completeness_mm'], '.2f')} | "
            f"{fmt(r['accuracy_mm'], '.2f')} | {fmt(r['sliver5'], '.4f')} | "
            f"{r['time_s']:.1f} | {fmt(r['folds'], '.4f')} | {fmt(r['spikes'], '.4f')} | "
            f"{fmt(r['far3'], '.4f')} | {fmt(r['grey'], '.4f')} | {pose} |")


# The issue's three measures: a stage may not make any of them worse.
METRICS = [("F@2mm", "f2", -1, ".4f", ""), ("completeness", "completeness_mm", 1, ".3f", " mm"),
           ("invented", "invented", 1, ".3%", "")]
# Where a stage shows what it is for: the three, and the finer F-score and accuracy.
GAIN_METRICS = [("F@1mm", "f1", -1, ".4f", "")] + METRICS + [
    ("accuracy", "accuracy_mm", 1, ".3f", " mm")]


def paired(base, skip, key, sign):
    """Over the seeds both ran: the means of `key` with and without the stage, and the paired
    differences signed so that > 0 is worse with the stage: (with, without, mean difference,
    its standard error, seeds on which the stage was better)."""
    seeds = sorted(set(base) & set(skip))
    d = np.array([sign * (base[s][key] - skip[s][key]) for s in seeds])
    se = float(d.std(ddof=1) / np.sqrt(len(d))) if len(d) > 1 else 0.0
    with_ = float(np.mean([base[s][key] for s in seeds]))
    without = float(np.mean([skip[s][key] for s in seeds]))
    return with_, without, float(d.mean()), se, int((d < 0).sum())


def is_bust(obj):
    return obj in BUSTS_WITH_TARGETS or OBJSET.get(obj, {}).get("kind") == "bust"


def fill_far(r):
    """The fill stage's points farther than 5 mm from the truth (share), or None."""
    f = (r.get("fill_points") or {}).get("all")
    return f["over5"] if f else None


def targets(obj, base):
    """[(target, held on every seed)] of an object's default runs: on the busts, F@2mm >= 0.96,
    invented <= 0.5%, completeness <= 1.0 mm; on every object with truth, the fill stage's
    points farther than 5 mm <= 2% (held when the fill stage added no point)."""
    base = list(base)
    t = []
    if is_bust(obj):
        t = [("F@2mm >= 0.96", min(r["f2"] for r in base) >= 0.96),
             ("invented <= 0.5%", max(r["invented"] for r in base) <= 0.005),
             ("completeness <= 1.0 mm", max(r["completeness_mm"] for r in base) <= 1.0)]
    if obj != "person":
        far = [fill_far(r) or 0.0 for r in base]
        t.append(("fill > 5 mm <= 2%", max(far) <= FILL_FAR_TARGET))
    return t


SUMMARY_VARIANTS = ["default"] + [f"skip-{s}" for s in STAGES] + ["o3d-spr", "o3d-spr-trim"]


def summary(rows):
    """Per object (means over the seeds): F@2mm / invented / completeness mm of every variant
    run, the fill stage's points farther than 5 mm (default job) and the targets."""
    by = {}
    for r in rows:
        by.setdefault(r["object"], {}).setdefault(r["variant"], []).append(r)
    variants = [v for v in SUMMARY_VARIANTS if any(v in x for x in by.values())]
    lines = ["| object | kind | " + " | ".join(variants) + " | fill > 5 mm | targets |",
             "|---|---|" + "---|" * (len(variants) + 2)]
    for obj, v in by.items():
        if obj == "person":
            continue
        cells = []
        for var in variants:
            rs = v.get(var)
            if not rs or rs[0]["f2"] is None:
                cells.append("-")
                continue
            m = lambda k: float(np.mean([r[k] for r in rs]))  # noqa: E731
            cells.append(f"{m('f2'):.3f} / {100 * m('invented'):.2f}% / "
                         f"{m('completeness_mm'):.2f}")
        base = v.get("default") or []
        far = [fill_far(r) for r in base]
        far = [x for x in far if x is not None]
        t = targets(obj, base) if base and base[0]["f2"] is not None else []
        kind = OBJSET.get(obj, {}).get("kind") or ("bust" if is_bust(obj) else
                                                   "animal" if obj == "bunny" else "-")
        lines.append(f"| {obj} | {kind} | " + " | ".join(cells) + " | " +
                     (f"{100 * max(far):.2f}%" if far else "-") + " | " +
                     (", ".join(f"{n}: {'yes' if ok else '**NO**'}" for n, ok in t) or "-") +
                     " |")
    return lines


def verdicts(rows):
    """Per object and stage: the paired differences default - skip-STAGE over the seeds. A stage
    "HURTS" when F@2mm, completeness or invented surface is worse on the mean by more than twice
    the standard error of the paired difference (the seeds' spread; with one seed any worse
    digit counts); "no measurable harm" when one is worse on the mean but within that spread;
    "earns its place" when none is worse on the mean. "Measurably better" lists the measures
    (those three, F@1mm and accuracy) that the stage improves by more than twice the standard
    error, with the number of seeds on which it did."""
    out = []
    by = {}
    for r in rows:
        by.setdefault(r["object"], {}).setdefault(r["variant"], {})[r["seed"]] = r
    for obj, v in by.items():
        parts = []
        base = v.get("default", {})
        if obj == "person" or not base or any(r["f2"] is None for r in base.values()):
            out.append(f"- {obj}: no ground truth (or no default run): no stage verdict")
            continue
        for stage in STAGES:
            skip = v.get(f"skip-{stage}")
            if not skip:
                continue
            n = len(set(base) & set(skip))
            worse, unsure, gains = [], [], []
            for name, key, sign, spec, unit in METRICS:
                with_, without, mean, se, _ = paired(base, skip, key, sign)
                detail = (f"{name} {with_:{spec}}{unit} vs {without:{spec}}{unit} without" +
                          (f", paired difference {abs(mean):{spec}}{unit} +- {se:{spec}}{unit}"
                           if n > 1 else ""))
                if mean > 2 * se:
                    worse.append(detail)
                elif mean > 0:
                    unsure.append(detail)
            if n > 1:
                for name, key, sign, spec, unit in GAIN_METRICS:
                    with_, without, mean, se, better = paired(base, skip, key, sign)
                    if mean < -2 * se:
                        gains.append(f"{name} {with_:{spec}}{unit} vs {without:{spec}}{unit} "
                                     f"({better}/{n} seeds)")
            if worse:
                verdict = f"{stage}: HURTS (" + "; ".join(worse) + ")"
            elif unsure:
                verdict = (f"{stage}: no measurable harm (worse on the mean, within the seeds' "
                           f"spread: " + "; ".join(unsure) + ")")
            else:
                verdict = f"{stage}: earns its place"
            if gains:
                verdict += "; measurably better: " + "; ".join(gains)
            parts.append(verdict)
        n = len(base)
        line = f"- {obj} ({n} seed{'s' if n > 1 else ''}): " + (
            "; ".join(parts) if parts else "no --skip variant run")
        t = targets(obj, base.values())
        if t:
            line += "; targets (every seed): " + ", ".join(
                f"{n} {'yes' if ok else 'NO'}" for n, ok in t)
        out.append(line)
    return out


def mean_rows(rows):
    """One row per object and variant: the mean over the seeds (time included)."""
    groups = {}
    for r in rows:
        groups.setdefault((r["object"], r["variant"]), []).append(r)
    out = []
    for (obj, var), rs in groups.items():
        m = dict(rs[0])
        m["seed"] = f"mean of {len(rs)}"
        for k, x in rs[0].items():
            if k in ("object", "variant", "seed") or x is None or isinstance(x, (str, dict)):
                continue
            m[k] = float(np.mean([r[k] for r in rs]))
        out.append(m)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--objects", default=None,
                    help="comma list (default: bunny,max_planck,bust_man_wreath,person; with "
                    "--objects-dir or --variety: every object of the set; 'all' = the set)")
    ap.add_argument("--objects-dir", default=None,
                    help="an object set made by validation/quality/variety/objects.py --out DIR")
    ap.add_argument("--variety", action="store_true",
                    help="make the variety object set in WORK/objects and use it")
    ap.add_argument("--shared", default=variety.SHARED,
                    help="--variety: the meshes folder of ../shared/data (the busts)")
    ap.add_argument("--variants", default=",".join(ALL_VARIANTS))
    ap.add_argument("--bin", default="build/bin", help="folder of the rgbd-* tools")
    ap.add_argument("--eval-bin", default=None,
                    help="folder of the rgbd-eval that scores (default --bin)")
    ap.add_argument("--work", default=None, help="work folder (default: a new temporary one)")
    ap.add_argument("--person-frames", default="0:50", help="frame positions A:B[:STEP]")
    ap.add_argument("--seed", type=int, default=None, help="one seed (same as --seeds N)")
    ap.add_argument("--seeds", default="1",
                    help="comma-separated seeds of the synthetic rings (the person: the first)")
    ap.add_argument("--chain", default="auto", choices=["auto", "reconstruct", "pipe"])
    ap.add_argument("--scene", default=None, metavar="ARGS",
                    help="rgbd-synth scene options for every ring object of the set instead of "
                    "its own (e.g. \"--scene room\": floor, walls, clutter, a person)")
    ap.add_argument("--out", default=None, help="also write the table to this markdown file")
    a = ap.parse_args()
    a.work = os.path.abspath(a.work or tempfile.mkdtemp(prefix="ablation_"))
    os.makedirs(a.work, exist_ok=True)
    if a.variety and a.objects_dir:
        sys.exit("ablation: --variety and --objects-dir exclude each other")
    if a.variety:
        a.objects_dir = os.path.join(a.work, "objects")
        variety.make(a.objects_dir, None, a.shared)
    if a.objects_dir:
        OBJSET.update(variety.load(os.path.abspath(a.objects_dir)))
    if a.scene is not None:
        if not OBJSET:
            sys.exit("ablation: --scene needs an object set (--objects-dir or --variety)")
        for entry in OBJSET.values():
            if entry.get("rig", "ring") == "ring":
                entry["scene"] = a.scene.split()
    if a.objects is None or a.objects == "all":
        a.objects = ",".join(OBJSET) if OBJSET else "bunny,max_planck,bust_man_wreath,person"
    a.objects = [x for x in a.objects.split(",") if x]
    a.variants = [x for x in a.variants.split(",") if x]
    a.seeds = [a.seed] if a.seed is not None else [int(x) for x in a.seeds.split(",") if x]
    if not a.seeds:
        sys.exit("ablation: no seed")
    for v in a.variants:
        if v not in ALL_VARIANTS:
            sys.exit(f"ablation: unknown variant {v} ({', '.join(ALL_VARIANTS)})")
    for o in a.objects:
        if o not in ("bunny", "person") and o not in BUSTS and o not in OBJSET:
            sys.exit(f"ablation: unknown object {o}")
    # The busts and the person come from ../shared/data beside the checkout; the bunny ships
    # with Debian's libcgal-dev.
    missing = [o for o in a.objects if o != "bunny" and o not in OBJSET and not os.path.exists(
        PERSON if o == "person" else os.path.join(DATA, BUSTS[o][0]))]
    for o in missing:
        print(f"ablation: skipping {o}: its data is not in {os.path.dirname(DATA)}",
              file=sys.stderr)
    a.objects = [o for o in a.objects if o not in missing]
    if not a.objects:
        sys.exit("ablation: no object to run")
    b = os.path.abspath(a.bin)
    eb = os.path.abspath(a.eval_bin or a.bin)
    for tool in ("rgbd-synth", "rgbd-cloud", "rgbd-reconstruct"):
        if not os.access(os.path.join(b, tool), os.X_OK):
            sys.exit(f"ablation: {b}/{tool} is absent (--bin: the folder of the rgbd-* tools)")
    chain = a.chain
    if chain == "auto":
        chain = "reconstruct" if has_skip(b) else "pipe"
    elif chain == "reconstruct" and any(v.startswith("skip-") for v in a.variants) and \
            not has_skip(b):
        sys.exit(f"ablation: {b}/rgbd-reconstruct has no --skip")
    # The commit measured: read at the start (the tree may move on during a long run).
    head = subprocess.run(["git", "-C", HERE, "rev-parse", "--short", "HEAD"],
                          capture_output=True, text=True).stdout.strip() or "?"
    dirty = subprocess.run(["git", "-C", HERE, "status", "--porcelain", "--untracked-files=no"],
                           capture_output=True, text=True).stdout.strip()
    head += " (with uncommitted changes)" if dirty else ""
    t_start = time.perf_counter()
    print(f"work {a.work}; chain {chain}; bin {b}; eval {eb}", file=sys.stderr, flush=True)
    rows, extra = [], []
    for obj in a.objects:
        for seed in (a.seeds[:1] if obj == "person" else a.seeds):
            run_object(obj, a, b, eb, chain, rows, extra, seed)
    shown = rows if len(a.seeds) == 1 else mean_rows(rows) + rows
    lines = [HEADER] + [table_row(r) for r in shown]
    verdict = verdicts(rows)
    fill_lines = ["| object | seed | mechanism | points added | max distance mm | > 3 mm | > 5 mm |",
                  "|---|---|---|---|---|---|---|"]
    for r in rows:
        for name, f in (r.get("fill_points") or {}).items():
            fill_lines.append(f"| {r['object']} | {r['seed']} | {name} | {f['points']} | "
                              f"{f['max_mm']:.2f} | {100 * f['over3']:.2f}% | "
                              f"{100 * f['over5']:.2f}% |")
    if len(fill_lines) > 2:
        lines += ["", "The fill stage's added points against the true surface (default job):", ""]
        lines += fill_lines
    lines += ["", "Per object (mean over the seeds): F@2mm / invented / completeness mean mm of "
              "every variant; the fill stage's points farther than 5 mm from the truth (default "
              "job); the targets on every seed:", ""] + summary(rows)
    if OBJSET:
        lines += ["", "Objects (rgbd-synth arguments as run):", ""]
        for o in a.objects:
            if o in OBJSET:
                e = OBJSET[o]
                lines.append(f"- {o} ({e['kind']}): {' '.join(set_arguments(e, b))}; "
                             f"{e['provenance']}")
    table = "\n".join(lines)
    print(table)
    print()
    print("\n".join(verdict))
    total = time.perf_counter() - t_start
    print(f"\n(total {total:.0f} s)")
    with open(os.path.join(a.work, "ablation.json"), "w") as f:
        json.dump({"rows": rows, "runs": extra}, f, indent=1, default=str)
    if a.out:
        cmd = " ".join(shlex.quote(x) for x in [sys.argv[0]] + sys.argv[1:])
        cores = len(os.sched_getaffinity(0))
        with open(a.out, "w") as f:
            f.write(f"# Ablation of rgbd-reconstruct's stages ({datetime.date.today()})\n\n"
                    f"- commit {head}; machine: {cores} cores (nproc), shared\n"
                    f"- command: `{cmd}`\n- chain: {chain}; seeds {a.seeds}; person frames "
                    f"{a.person_frames}; total {total:.0f} s\n\n{table}\n\n" +
                    "\n".join(verdict) + "\n")
        print(f"wrote {a.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
