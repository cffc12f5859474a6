#!/usr/bin/python3
"""Noise-removal quality of rgbd-clean --distance / --density against Open3D 0.16.

Renders 8-Kinect ring captures of the two busts with build/bin/rgbd-synth (default noise),
back-projects them with rgbd-cloud (default 0.6 m crop around the rig centre: what users get),
runs rgbd-clean with --mark (the `noise` flag plus the `pixel` property of every point are read
back with the small PLY reader below) and Open3D's remove_statistical_outlier /
remove_radius_outlier (tutorial values and the best of a small grid) on the same points, and
prints precision / recall / F1 of noise detection against gt/<sensor>/labels (positives: flying
pixels, label 2, and outliers, label 3; negatives: surface, label 1).

Usage: measure_denoise.py [--bin BUILD/bin] [--work DIR] [--seed S]
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

import numpy as np
import open3d as o3d

DATA = "/work/shared/data/meshes"
BUSTS = [
    ("max_planck", f"{DATA}/max_planck/max-planck.obj", ["--height-m", "0.6"]),
    ("bust_man_wreath", f"{DATA}/danish_statues/BustManWreath_welded.ply",
     ["--height-m", "0.605", "--up", "y"]),
]
PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
             "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
             "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
             "float64": "f8"}


def read_stream(path):
    """Documents of a binary little-endian PLY stream: (comments, vertex record array)."""
    data = open(path, "rb").read()
    pos, docs = 0, []
    while pos < len(data):
        end = data.index(b"end_header\n", pos) + len(b"end_header\n")
        header = data[pos:end].decode("ascii", "replace").splitlines()
        comments, fields, count, element, faces = [], [], 0, None, 0
        for line in header:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "comment":
                comments.append(line[len("comment "):])
            elif parts[0] == "element":
                element = parts[1]
                if element == "vertex":
                    count = int(parts[2])
                elif element == "face":
                    faces = int(parts[2])
            elif parts[0] == "property" and element == "vertex":
                fields.append((parts[-1], "<" + PLY_TYPES[parts[1]]))
            elif parts[0] == "format" and parts[1] != "binary_little_endian":
                sys.exit(f"{path}: only binary_little_endian streams are supported")
        if faces:
            sys.exit(f"{path}: meshes are not supported here")
        dtype = np.dtype(fields)
        verts = np.frombuffer(data, dtype=dtype, count=count, offset=end)
        pos = end + count * dtype.itemsize
        docs.append((comments, verts))
    return docs


def meta(comments, key):
    for c in comments:
        m = re.match(r"rgbd:" + re.escape(key) + r"\s+(.*)$", c)
        if m:
            return m.group(1).strip()
    return None


def run(cmd, **kw):
    r = subprocess.run(cmd, shell=True, capture_output=True, text=True, **kw)
    if r.returncode != 0:
        sys.exit(f"failed: {cmd}\n{r.stderr}")
    return r.stdout


def labels_of(cap, docs):
    """gt label of every point of every document (by sensor, frame index and pixel)."""
    out = []
    for comments, v in docs:
        sensor = meta(comments, "view.sensor")
        frame = int(meta(comments, "view.frame_index") or 0)
        path = os.path.join(cap, "gt", sensor, "labels", f"{frame:06d}.png")
        img = np.asarray(o3d.io.read_image(path)).reshape(-1)
        out.append(img[v["pixel"].astype(np.int64)])
    return out


def prf(pred, label):
    """precision, recall, F1 of noise detection, surface loss; labels 2, 3 = noise, 1 = surface."""
    use = np.isin(label, [1, 2, 3])
    pred, pos = pred[use], np.isin(label[use], [2, 3])
    tp = np.sum(pred & pos)
    p = tp / max(1, np.sum(pred))
    r = tp / max(1, np.sum(pos))
    f = 2 * p * r / max(1e-12, p + r)
    loss = np.sum(pred & ~pos) / max(1, np.sum(~pos))
    return p, r, f, loss


def open3d_rows(clouds, labels, per_view):
    """Open3D SOR / ROR at tutorial values and the best of a grid, per view or merged."""
    def decide(fn):
        preds = []
        groups = [(c, l) for c, l in zip(clouds, labels)] if per_view else \
            [(np.concatenate(clouds), np.concatenate(labels))]
        for xyz, _ in groups:
            pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(xyz.astype(np.float64)))
            _, kept = fn(pc)
            pred = np.ones(len(xyz), bool)
            pred[np.asarray(kept, dtype=np.int64)] = False
            preds.append(pred)
        return prf(np.concatenate(preds), np.concatenate([l for _, l in groups]))

    rows = [("O3D SOR(20, 2.0)", decide(lambda pc: pc.remove_statistical_outlier(20, 2.0))),
            ("O3D ROR(16, 0.05)", decide(lambda pc: pc.remove_radius_outlier(16, 0.05)))]
    best = max(((f"O3D SOR({k}, {s}) best", decide(lambda pc, k=k, s=s:
                                                    pc.remove_statistical_outlier(k, s)))
                for k in (10, 20, 50) for s in (0.5, 1.0, 2.0, 3.0)), key=lambda r: r[1][2])
    rows.append(best)
    best = max(((f"O3D ROR({n}, {r}) best", decide(lambda pc, n=n, r=r:
                                                    pc.remove_radius_outlier(n, r)))
                for n in (4, 8, 16, 32) for r in (0.005, 0.01, 0.02, 0.05)),
               key=lambda r: r[1][2])
    rows.append(best)
    return rows


def ours(path, cap):
    docs = read_stream(path)
    lab = labels_of(cap, docs)
    pred = np.concatenate([d[1]["noise"].astype(bool) if "noise" in d[1].dtype.names
                           else np.zeros(len(d[1]), bool) for d in docs])
    return prf(pred, np.concatenate(lab)), docs, lab


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bin", default=os.path.join(os.path.dirname(__file__), "../../../build/bin"))
    ap.add_argument("--work", default=None)
    ap.add_argument("--seed", default="1")
    a = ap.parse_args()
    b = os.path.abspath(a.bin)
    work = a.work or tempfile.mkdtemp(prefix="rgbd_denoise_")
    print(f"# work dir {work}; tools {b}; Open3D {o3d.__version__}; rgbd-cloud default crop")
    print("| capture | stage | method | precision | recall | F1 | surface removed |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for name, mesh, args in BUSTS:
        cap = os.path.join(work, name)
        if not os.path.exists(os.path.join(cap, "rig.json")):
            run(f"{b}/rgbd-synth {mesh} -o {cap} {' '.join(args)} --seed {a.seed} -q")
        views = os.path.join(work, f"{name}_views.ply")
        run(f"{b}/rgbd-cloud {cap} -q > {views}")
        # Before alignment: --distance per view vs Open3D per view.
        marked = os.path.join(work, f"{name}_distance.ply")
        run(f"{b}/rgbd-clean --distance --mark -q {views} > {marked}")
        score, docs, lab = ours(marked, cap)
        rows = [("rgbd-clean --distance", score)]
        clouds = [np.stack([d[1]["x"], d[1]["y"], d[1]["z"]], 1) for d in docs]
        rows += open3d_rows(clouds, lab, per_view=True)
        for method, (p, r, f, loss) in rows:
            print(f"| {name} | per view | {method} | {p:.3f} | {r:.3f} | {f:.3f} | "
                  f"{100 * loss:.2f}% |")
        # After alignment (raw views aligned, all labels intact): --density vs Open3D merged.
        aligned = os.path.join(work, f"{name}_aligned.ply")
        run(f"{b}/rgbd-align -q {views} > {aligned}")
        marked = os.path.join(work, f"{name}_density.ply")
        run(f"{b}/rgbd-clean --density --mark -q {aligned} > {marked}")
        score, docs, lab = ours(marked, cap)
        rows = [("rgbd-clean --density", score)]
        clouds = [np.stack([d[1]["x"], d[1]["y"], d[1]["z"]], 1) for d in docs]
        rows += open3d_rows(clouds, lab, per_view=False)
        # The full pipeline: --distance, align, --density (noise flag of both passes).
        both = os.path.join(work, f"{name}_both.ply")
        run(f"{b}/rgbd-clean --distance --mark -q {views} | {b}/rgbd-align -q | "
            f"{b}/rgbd-clean --density --mark -q > {both}")
        rows.append(("--distance --mark, align, --density --mark", ours(both, cap)[0]))
        for method, (p, r, f, loss) in rows:
            print(f"| {name} | merged | {method} | {p:.3f} | {r:.3f} | {f:.3f} | "
                  f"{100 * loss:.2f}% |")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
