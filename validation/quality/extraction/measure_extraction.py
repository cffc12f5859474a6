#!/usr/bin/python3
"""Object extraction against the truth labels of rgbd-synth scenes (issue 35).

For each capture (made by rgbd-synth with --floor / --walls / --clutter / --people / --plinth /
--scene room, so gt/<sensor>/segment/NNNNNN.png labels every depth pixel: 1 subject, 2 support,
3 background, 4 a return where the clean scene has nothing), runs
    rgbd-cloud CAP --no-extract      (every point of the depth window)
    rgbd-cloud CAP                   (the default: object extraction)
and scores the kept points by their pixels' labels:
    precision = kept subject points / kept points
    recall    = kept subject points / subject points of the depth window
plus the share of the support (floor, plinth) and background points kept. Flying pixels and
outliers count with the label of their pixel's clean surface (rgbd-synth's convention), so
they lower the precision until the distance cleaning removes them: the figures after
`rgbd-clean --distance` are given too.

    measure_extraction.py --bin build/bin CAP [CAP ...] [--out results.md]
"""
import argparse
import os
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
from rgbd_stream import meta, read_stream  # noqa: E402

import open3d as o3d  # noqa: E402  (Debian's python3-open3d reads the 8-bit PNGs)


def labels_of(cap, comments):
    """The segment image of a view from its rgbd:view.source (the depth frame)."""
    source = meta(comments, "view.source")
    sensor = os.path.basename(os.path.dirname(os.path.dirname(source)))
    name = os.path.splitext(os.path.basename(source))[0] + ".png"
    path = os.path.join(cap, "gt", sensor, "segment", name)
    if not os.path.exists(path):
        raise SystemExit(f"{path}: no segment image (a capture of rgbd-synth with a scene?)")
    return np.asarray(o3d.io.read_image(path)).reshape(-1)


def count(cap, stream):
    """Per label: number of points of the stream (all views)."""
    out = np.zeros(5, int)
    for comments, rec in read_stream(stream):
        lab = labels_of(cap, comments)
        out += np.bincount(lab[rec["pixel"].astype(np.int64)], minlength=5)[:5]
    return out


def run(cmd, out):
    with open(out, "wb") as f:
        subprocess.run(cmd, stdout=f, check=True)


def measure(binary, cap, work):
    os.makedirs(work, exist_ok=True)
    rows = {}
    allp = os.path.join(work, "all.ply")
    run([os.path.join(binary, "rgbd-cloud"), cap, "--no-extract", "-q"], allp)
    ext = os.path.join(work, "extracted.ply")
    run([os.path.join(binary, "rgbd-cloud"), cap, "-q"], ext)
    for name, path in (("all", allp), ("extracted", ext)):
        rows[name] = count(cap, path)
        cleaned = path + ".clean.ply"
        subprocess.run([os.path.join(binary, "rgbd-clean"), "--distance", path, "-o", cleaned,
                        "-q"], check=True)
        rows[name + "+distance"] = count(cap, cleaned)
    return rows


def scores(rows, kept, base):
    k, b = rows[kept], rows[base]
    subject = k[1]
    return {"precision": subject / max(1, k[1:].sum()),
            "recall": subject / max(1, b[1]),
            "support kept": k[2] / max(1, b[2]),
            "background kept": k[3] / max(1, b[3])}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("captures", nargs="+")
    ap.add_argument("--bin", default="build/bin")
    ap.add_argument("--work", default="/tmp/measure_extraction")
    ap.add_argument("--out", default="")
    a = ap.parse_args()
    lines = ["| capture | points (subject / support / background) | precision | recall | "
             "support kept | background kept | after --distance: precision / recall |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for cap in a.captures:
        rows = measure(a.bin, cap, os.path.join(a.work, os.path.basename(cap.rstrip("/"))))
        s = scores(rows, "extracted", "all")
        d = scores(rows, "extracted+distance", "all+distance")
        b = rows["all"]
        lines.append(f"| {os.path.basename(cap.rstrip('/'))} | {b[1]} / {b[2]} / {b[3] + b[4]} | "
                     f"{s['precision']:.4f} | {s['recall']:.4f} | {s['support kept']:.4f} | "
                     f"{s['background kept']:.4f} | {d['precision']:.4f} / {d['recall']:.4f} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if a.out:
        with open(a.out, "w") as f:
            f.write(text)


if __name__ == "__main__":
    main()
