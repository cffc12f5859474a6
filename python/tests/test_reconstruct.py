"""The target of issue 37 on a synthetic capture: rgbd_toolkit.reconstruct(CAPTURE) returns the
mesh rgbd-reconstruct CAPTURE -o m.ply writes (vertices within 1e-6 m, identical faces), and the
stages called one by one from Python (the README's pipe) give that mesh too. Prints the wall
times of the tool and of reconstruct() (the Python layer's overhead, docs/python.md)."""

import math
import os
import subprocess
import tempfile
import time
import unittest

import numpy as np

import rgbd_toolkit as rt

BIN = os.environ.get("RGBD_BIN", "")


def write_bumpy_ellipsoid_off(path, nu=48, nv=24, rx=0.3, ry=0.5, rz=0.25):
    """The pipeline tests' object (tests/support/ellipsoid_off.hpp): a UV ellipsoid whose x and
    z radii carry the bump 1 + 0.08 sin(3 phi) sin(2 theta)."""
    vertices = [(0.0, ry, 0.0)]
    for j in range(1, nv):
        for i in range(nu):
            th, ph = math.pi * j / nv, 2 * math.pi * i / nu
            b = 1.0 + 0.08 * math.sin(3 * ph) * math.sin(2 * th)
            vertices.append((rx * b * math.sin(th) * math.cos(ph), ry * math.cos(th),
                             rz * b * math.sin(th) * math.sin(ph)))
    vertices.append((0.0, -ry, 0.0))
    south = nu * (nv - 1) + 1

    def vid(j, i):
        return 1 + (j - 1) * nu + (i % nu)

    faces = [(0, vid(1, i + 1), vid(1, i)) for i in range(nu)]
    for j in range(1, nv - 1):
        for i in range(nu):
            faces.append((vid(j, i), vid(j, i + 1), vid(j + 1, i + 1)))
            faces.append((vid(j, i), vid(j + 1, i + 1), vid(j + 1, i)))
    faces += [(south, vid(nv - 1, i), vid(nv - 1, i + 1)) for i in range(nu)]
    with open(path, "w") as off:
        off.write("OFF\n%d %d 0\n" % (len(vertices), len(faces)))
        off.writelines("%.9g %.9g %.9g\n" % v for v in vertices)
        off.writelines("3 %d %d %d\n" % f for f in faces)


@unittest.skipUnless(BIN and all(os.path.exists(os.path.join(BIN, t))
                             for t in ("rgbd-synth", "rgbd-reconstruct")),
                     "needs RGBD_BIN with rgbd-synth and rgbd-reconstruct (ctest sets it)")
class ReconstructEqualsTheTool(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory(prefix="rgbd_python_reconstruct_")
        cls.dir = cls.tmp.name
        write_bumpy_ellipsoid_off(os.path.join(cls.dir, "blob.off"))
        cls.capture = os.path.join(cls.dir, "cap")
        subprocess.run([os.path.join(BIN, "rgbd-synth"), "blob.off", "-o", "cap", "--sensors", "6",
                        "--height-m", "0.5", "--seed", "3", "-q"], cwd=cls.dir, check=True)
        # The tool: rgbd-reconstruct CAPTURE -o m.ply (with its report and evaluation).
        start = time.perf_counter()
        subprocess.run([os.path.join(BIN, "rgbd-reconstruct"), cls.capture, "-o",
                        os.path.join(cls.dir, "m.ply"), "-q"], check=True)
        cls.cli_seconds = time.perf_counter() - start
        # The same from Python.
        start = time.perf_counter()
        cls.mesh = rt.reconstruct(cls.capture)
        cls.python_seconds = time.perf_counter() - start
        print("\nrgbd-reconstruct: %.2f s wall (process); rgbd_toolkit.reconstruct: %.2f s wall; "
              "stages in the tool's report and in reconstruct()'s report below"
              % (cls.cli_seconds, cls.python_seconds))

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def assert_same_mesh(self, mesh, reference):
        self.assertEqual(mesh.vertices.shape, reference.vertices.shape)
        np.testing.assert_array_equal(mesh.faces, reference.faces)
        self.assertLessEqual(np.abs(mesh.vertices - reference.vertices).max(), 1e-6)
        np.testing.assert_array_equal(mesh.colors, reference.colors)

    def test_reconstruct_returns_the_tools_mesh(self):
        tool = rt.read_mesh(os.path.join(self.dir, "m.ply"))
        self.assertGreater(len(tool.faces), 1000)
        self.assert_same_mesh(self.mesh, tool)
        # A closed mesh (the watertight default): every edge in exactly two faces.
        f = self.mesh.faces
        edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        _, counts = np.unique(edges, axis=0, return_counts=True)
        self.assertTrue((counts == 2).all())
        stages = [s["stage"] for s in self.mesh.report["stages"]]
        self.assertEqual(stages[0], "clouds")
        self.assertEqual(stages[-1], "mesh")
        for s in self.mesh.report["stages"]:
            print("  %-9s %.2f s" % (s["stage"], s["time_s"]))

    def test_the_stages_one_by_one_give_the_same_mesh(self):
        capture = rt.read_capture(self.capture)
        views = rt.clouds(capture)
        self.assertEqual(len(views), 6)
        rt.clean_distance(views)
        rt.upsample(views, capture)
        rt.align(views)
        rt.clean_density(views)
        rt.fill(views)
        mesh = rt.mesh(views, watertight=True)
        self.assert_same_mesh(mesh, self.mesh)

    @unittest.skipUnless(BIN and os.path.exists(os.path.join(BIN, "rgbd-texture")),
                         "needs rgbd-texture in RGBD_BIN")
    def test_texture_writes_the_tools_model(self):
        tool_obj = os.path.join(self.dir, "tool.obj")
        subprocess.run([os.path.join(BIN, "rgbd-texture"), os.path.join(self.dir, "m.ply"),
                        "--capture", self.capture, "-o", tool_obj, "-q"], check=True)
        obj = os.path.join(self.dir, "python.obj")
        report = rt.texture(rt.read_mesh(os.path.join(self.dir, "m.ply")), self.capture, obj)
        self.assertGreater(report["atlas"]["charts"], 0)

        def geometry(path):  # vertices, texture coordinates and faces of an OBJ
            with open(path) as f:
                return [l for l in f if l.split(" ")[0] in ("v", "vt", "f")]

        lines = geometry(obj)
        self.assertGreater(len(lines), 1000)
        # Compared whole, not by assertEqual (its diff of 100k lines would take minutes).
        self.assertTrue(lines == geometry(tool_obj), "the OBJ differs from rgbd-texture's")
        with open(os.path.join(self.dir, "python.png"), "rb") as a, \
                open(os.path.join(self.dir, "tool.png"), "rb") as b:
            self.assertTrue(a.read() == b.read(), "the atlas differs from rgbd-texture's")
        self.assertTrue(os.path.exists(os.path.join(self.dir, "python.mtl")))
        with self.assertRaisesRegex(ValueError, "texture writes a .obj"):
            rt.texture(self.mesh, self.capture, os.path.join(self.dir, "model.ply"))
        self.assertFalse(os.path.exists(os.path.join(self.dir, "model.ply")))

    def test_progress_reaches_every_long_stage(self):
        seen = {}

        def progress(stage, fraction):
            seen[stage] = max(seen.get(stage, 0.0), fraction)

        rt.reconstruct(self.capture, skip=["upsample", "fill"], progress=progress)
        for stage in ("clouds", "align", "density", "mesh"):
            self.assertIn(stage, seen)
            self.assertGreater(seen[stage], 0.0)


if __name__ == "__main__":
    unittest.main()
