#!/usr/bin/env python3
"""The README's pipeline in Python (docs/python.md): a capture folder -> a coloured, closed mesh,
stage by stage on numpy-backed views, then the one-call reconstruct(), and the evaluation against
the capture's ground truth when it has some (rgbd-synth writes gt/mesh.ply).

    rgbd-synth mesh.obj -o cap/ --height-m 0.6
    PYTHONPATH=PREFIX/lib/python3/dist-packages python3 reconstruct.py cap/ bust.ply
"""
import os
import sys

import numpy as np

import rgbd_toolkit as rt


def progress(stage, fraction):
    print("\r%-12s %3.0f%%" % (stage, 100 * fraction), end="", file=sys.stderr, flush=True)


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: reconstruct.py CAPTURE_DIR MESH.ply")
    capture_dir, mesh_path = sys.argv[1:]
    capture = rt.read_capture(capture_dir)
    print(capture, [s.id for s in capture.sensors])

    # rgbd-cloud cap/ | rgbd-clean --distance | rgbd-upsample | rgbd-align
    #   | rgbd-clean --density | rgbd-fill | rgbd-mesh --watertight -o bust.ply
    views = rt.clouds(capture, progress=progress)
    rt.clean_distance(views)
    rt.upsample(views, capture, progress=progress)
    report = rt.align(views, progress=progress)
    for v in report["align"]["views"]:
        print("\nview %d (%s): %s" % (v["view"], v["sensor"], v["verdict"]), end="")
    rt.clean_density(views, progress=progress)
    rt.fill(views, progress=progress)
    print("\n%d views, %d points" % (len(views), sum(len(v) for v in views)))
    mesh = rt.mesh(views, watertight=True, progress=progress)
    mesh.save(mesh_path)
    print("\n%s: %d vertices, %d faces" % (mesh_path, len(mesh.vertices), len(mesh.faces)))

    # The same chain in one call (= rgbd-reconstruct cap/ -o bust.ply): the same mesh.
    same = rt.reconstruct(capture, progress=progress)
    print("\nreconstruct(): same mesh:", np.array_equal(same.faces, mesh.faces)
          and np.abs(same.vertices - mesh.vertices).max() <= 1e-6)

    reference = os.path.join(capture_dir, "gt", "mesh.ply")
    if os.path.exists(reference):
        scores = rt.evaluate(mesh, reference)
        print("F-score@2mm %.3f, F-score@5mm %.3f" % (scores["fscore_2mm"], scores["fscore_5mm"]))


if __name__ == "__main__":
    main()
