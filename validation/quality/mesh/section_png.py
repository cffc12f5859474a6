#!/usr/bin/python3
"""Vertical section of meshes near the floor of a synthetic capture, as a PNG.

Draws where the plane through the true mesh's centroid, normal to x or y, cuts each mesh, over
the lowest --height-m above the floor (gt/scene.json floor_z): the truth (CAP/gt/mesh.ply) in
black, the first mesh in red, the second in blue, the floor in grey; 2 pixels per millimetre,
40 cm wide. For looking at a closed base against the truth (a skirt round a rounded bottom, a
base floating above the floor), as in validation/results/2026-12-08-skirts-carved-by-the-floor.md.

    /usr/bin/python3 validation/quality/mesh/section_png.py CAP OLD.ply NEW.ply --axis y -o s.png

Needs Debian's python3-open3d (reading meshes, writing the PNG) and numpy.
"""
import argparse
import json
import sys

import numpy as np
import open3d as o3d


def crossings(path, axis, centre):
    """The segments where the plane (coordinate `axis` = centre[axis]) cuts the mesh's triangles."""
    mesh = o3d.io.read_triangle_mesh(path)
    vertices, triangles = np.asarray(mesh.vertices), np.asarray(mesh.triangles)
    if len(triangles) == 0:
        sys.exit(f"{path}: no triangles")
    side = vertices[:, axis] - centre[axis]
    segments = []
    for t in triangles:
        points = []
        for i in range(3):
            a, b = t[i], t[(i + 1) % 3]
            if (side[a] < 0) != (side[b] < 0):
                s = side[a] / (side[a] - side[b])
                points.append(vertices[a] + s * (vertices[b] - vertices[a]))
        if len(points) == 2:
            segments.append(points)
    return np.array(segments).reshape(-1, 2, 3)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("capture", help="an rgbd-synth capture with gt/mesh.ply and gt/scene.json")
    parser.add_argument("old", help="the mesh drawn in red")
    parser.add_argument("new", help="the mesh drawn in blue")
    parser.add_argument("--axis", choices=["x", "y"], default="x", help="the section's normal")
    parser.add_argument("--height-m", type=float, default=0.1, help="how far above the floor")
    parser.add_argument("-o", "--out", required=True, help="the PNG to write")
    args = parser.parse_args()
    try:
        floor_z = json.load(open(args.capture + "/gt/scene.json"))["scene"]["floor_z"]
    except (OSError, KeyError, ValueError) as e:
        sys.exit(f"{args.capture}/gt/scene.json: no floor ({e})")
    truth = args.capture + "/gt/mesh.ply"
    centre = np.asarray(o3d.io.read_triangle_mesh(truth).vertices).mean(0)
    axis = {"x": 0, "y": 1}[args.axis]
    across = 1 - axis
    width, height, scale = 800, 400, 2000.0  # pixels, pixels per metre
    image = np.full((height, width, 3), 255, np.uint8)
    image[height - 20:height - 18, :] = (160, 160, 160)
    for path, colour in [(truth, (0, 0, 0)), (args.old, (220, 30, 30)), (args.new, (30, 60, 220))]:
        segments = crossings(path, axis, centre)
        segments = segments[(segments[:, :, 2] < floor_z + args.height_m).any(1)]
        for a, b in segments:
            for t in np.linspace(0, 1, 40):
                p = a + t * (b - a)
                u = int((p[across] - centre[across]) * scale + width / 2)
                v = int(height - 20 - (p[2] - floor_z) * scale)
                if 0 <= u < width and 0 <= v < height:
                    image[v, u] = colour
    o3d.io.write_image(args.out, o3d.geometry.Image(image))
    print("wrote", args.out)


if __name__ == "__main__":
    main()
