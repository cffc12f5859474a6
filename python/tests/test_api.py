"""The Python module's data types, readers and writers, options and errors (issue 37): numpy
round trips with known values, bad input (wrong shapes, NaN, out-of-range colours, missing
files, unknown options) as Python exceptions with the toolkit's messages, and a small stage
(mesh, evaluate) on a sampled sphere whose answer is known."""

import os
import tempfile
import unittest

import numpy as np

import rgbd_toolkit as rt


def tetrahedron():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    colors = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255], [10, 20, 30]], dtype=np.uint8)
    return vertices, faces, colors


def sphere_cloud(n=6000, radius=0.2, seed=1):
    """n points on a sphere (Fibonacci lattice) with outward normals and a colour by height."""
    i = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * i / n)
    theta = np.pi * (1 + 5 ** 0.5) * i
    normals = np.stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)], 1)
    colors = np.zeros((n, 3), dtype=np.uint8)
    colors[:, 0] = (128 + 127 * normals[:, 2]).astype(np.uint8)
    cloud = rt.PointCloud(radius * normals, normals, colors)
    cloud.frame = "world"
    return cloud


class PointClouds(unittest.TestCase):
    def test_arrays_round_trip(self):
        points = np.array([[0.1, 0.2, 0.3], [1.0, -2.0, 3.5]])
        normals = np.array([[0, 0, 1.0], [1.0, 0, 0]])
        colors = np.array([[1, 2, 3], [250, 251, 252]], dtype=np.uint8)
        pose = np.eye(4)
        pose[:3, 3] = [0.5, -0.25, 2.0]
        cloud = rt.PointCloud(points, normals, colors, pose)
        self.assertEqual(len(cloud), 2)
        np.testing.assert_array_equal(cloud.points, points)
        np.testing.assert_array_equal(cloud.normals, normals)
        np.testing.assert_array_equal(cloud.colors, colors)
        self.assertEqual(cloud.colors.dtype, np.uint8)
        np.testing.assert_array_equal(cloud.pose, pose)
        self.assertEqual(cloud.frame, "sensor")
        # Setters replace the values; the getters return copies.
        cloud.points = points * 2
        np.testing.assert_array_equal(cloud.points, points * 2)
        copy = cloud.points
        copy[0, 0] = 99
        self.assertEqual(cloud.points[0, 0], 0.2)
        cloud.normals = None
        self.assertIsNone(cloud.normals)
        self.assertIn("red", cloud.property_names())
        np.testing.assert_array_equal(cloud.property("green"), [2, 251])

    def test_bad_arrays_are_value_errors_naming_the_problem(self):
        with self.assertRaisesRegex(ValueError, r"points must be an N x 3 array, got shape \(4,\)"):
            rt.PointCloud(np.zeros(4))
        with self.assertRaisesRegex(ValueError, r"points must be an N x 3 array, got shape \(2, 2\)"):
            rt.PointCloud(np.zeros((2, 2)))
        with self.assertRaisesRegex(ValueError, "points: row 1 is not finite"):
            rt.PointCloud(np.array([[0, 0, 0], [np.nan, 0, 0]]))
        with self.assertRaisesRegex(ValueError, "normals has 1 rows, the cloud 2 points"):
            rt.PointCloud(np.zeros((2, 3)), normals=np.zeros((1, 3)))
        with self.assertRaisesRegex(ValueError, r"colors must be integers in 0\.\.255"):
            rt.PointCloud(np.zeros((1, 3)), colors=np.array([[0.5, 0.5, 0.5]]))
        with self.assertRaisesRegex(ValueError, "pose must be a 4 x 4 array"):
            rt.PointCloud(np.zeros((1, 3)), pose=np.eye(3))
        with self.assertRaisesRegex(ValueError, "pose last row must be 0 0 0 1"):
            rt.PointCloud(np.zeros((1, 3)), pose=np.ones((4, 4)))
        # InputError is a ValueError and the toolkit's own class.
        with self.assertRaises(rt.InputError):
            rt.PointCloud(np.zeros((2, 2)))

    def test_views_round_trip_through_a_view_stream(self):
        pose = np.eye(4)
        pose[:3, 3] = [1, 2, 3]
        a = rt.PointCloud(np.random.default_rng(1).normal(size=(50, 3)), pose=pose)
        a.id, a.sensor = 0, "k2_0"
        b = sphere_cloud(100)
        b.id, b.frame = 1, "world"
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "views.ply")
            rt.write_views([a, b], path)
            views = rt.read_views(path)
        self.assertEqual(len(views), 2)
        self.assertEqual((views[0].id, views[0].sensor, views[1].frame), (0, "k2_0", "world"))
        np.testing.assert_array_equal(views[0].pose, pose)
        np.testing.assert_allclose(views[0].points, a.points, atol=1e-6)
        np.testing.assert_array_equal(views[1].colors, b.colors)

    def test_open3d_round_trip(self):
        try:
            import open3d  # noqa: F401
        except ImportError:
            self.skipTest("open3d is not importable")
        cloud = sphere_cloud(200)
        back = rt.PointCloud.from_open3d(cloud.to_open3d())
        np.testing.assert_array_equal(back.points, cloud.points)
        np.testing.assert_array_equal(back.colors, cloud.colors)
        mesh = rt.Mesh(*tetrahedron())
        back = rt.Mesh.from_open3d(mesh.to_open3d())
        np.testing.assert_array_equal(back.faces, mesh.faces)
        np.testing.assert_array_equal(back.colors, mesh.colors)


class Meshes(unittest.TestCase):
    def test_arrays_and_files_round_trip(self):
        vertices, faces, colors = tetrahedron()
        mesh = rt.Mesh(vertices, faces, colors)
        np.testing.assert_array_equal(mesh.vertices, vertices)
        np.testing.assert_array_equal(mesh.faces, faces)
        np.testing.assert_array_equal(mesh.colors, colors)
        self.assertEqual(mesh.faces.dtype, np.int64)
        # The vertices are the mesh's own storage: read-only, no copy.
        self.assertFalse(mesh.vertices.flags.writeable)
        self.assertIsNotNone(mesh.vertices.base)
        with tempfile.TemporaryDirectory() as d:
            for name in ("t.ply", "t.off", "t.obj"):
                path = os.path.join(d, name)
                mesh.save(path)
                back = rt.read_mesh(path)
                np.testing.assert_allclose(back.vertices, vertices, atol=1e-6)
                np.testing.assert_array_equal(back.faces, faces)
            np.testing.assert_array_equal(rt.read_mesh(os.path.join(d, "t.ply")).colors, colors)

    def test_bad_meshes_are_value_errors(self):
        vertices, faces, _ = tetrahedron()
        with self.assertRaisesRegex(ValueError, "faces: row 1 names vertex 7 of 4"):
            rt.Mesh(vertices, np.array([[0, 1, 2], [0, 1, 7]]))
        with self.assertRaisesRegex(ValueError, "vertices: row 2 is not finite"):
            bad = vertices.copy()
            bad[2, 1] = np.inf
            rt.Mesh(bad, faces)
        with self.assertRaisesRegex(ValueError, "faces must be an N x 3 array"):
            rt.Mesh(vertices, np.array([0, 1, 2]))

    def test_missing_files_name_the_file(self):
        with tempfile.TemporaryDirectory() as d:
            missing = os.path.join(d, "missing.ply")
            with self.assertRaisesRegex((ValueError, OSError), "missing.ply"):
                rt.read_mesh(missing)
            with self.assertRaisesRegex((ValueError, OSError), "missing.ply"):
                rt.read_views(missing)
            with self.assertRaisesRegex((ValueError, OSError), "no_capture"):
                rt.read_capture(os.path.join(d, "no_capture"))
            with self.assertRaisesRegex((ValueError, OSError), "no_capture"):
                rt.reconstruct(os.path.join(d, "no_capture"))


class Stages(unittest.TestCase):
    def test_mesh_and_evaluate_on_a_sphere(self):
        views = [sphere_cloud()]
        before = views[0].points
        mesh = rt.mesh(views, watertight=True)
        np.testing.assert_array_equal(views[0].points, before)  # the views are not consumed
        radii = np.linalg.norm(mesh.vertices, axis=1)
        self.assertLess(np.abs(radii - 0.2).max(), 0.005)
        self.assertGreater(len(mesh.faces), 1000)
        self.assertIsInstance(mesh.report, dict)
        scores = rt.evaluate(mesh, mesh, samples=20000)
        self.assertGreater(scores["fscore_2mm"], 0.99)

    def test_unknown_options_are_type_errors_naming_them(self):
        with self.assertRaisesRegex(TypeError, "unexpected keyword argument 'colour_wieght'"):
            rt.align([], colour_wieght=1)
        with self.assertRaisesRegex(TypeError, "unexpected keyword argument 'skp'"):
            rt.reconstruct("nowhere", skp=["fill"])
        with self.assertRaisesRegex(TypeError, "option 'watertight' has the wrong type"):
            rt.mesh([sphere_cloud(100)], watertight="yes")
        with self.assertRaisesRegex(TypeError, r"views\[1\] is a str, not a PointCloud"):
            rt.mesh([sphere_cloud(100), "x"])

    def test_bad_option_values_are_value_errors_with_the_toolkit_messages(self):
        with self.assertRaisesRegex(ValueError, "skip: unknown stage 'colour' \\(valid: distance"):
            rt.reconstruct("nowhere", skip=["colour"])
        with self.assertRaisesRegex(ValueError, "upsample must be 4 or 8 \\(0 = off\\), not 5"):
            rt.reconstruct("nowhere", upsample=5)
        with self.assertRaisesRegex(ValueError, "noise_model: "):
            rt.clean_distance([], noise_model="kinect_v9")
        with self.assertRaisesRegex(ValueError, "crop_radius_m must be in \\[0, 100\\] m, got -1"):
            rt.clouds("nowhere", crop_radius_m=-1)
        with self.assertRaisesRegex(ValueError, "method"):
            rt.mesh([sphere_cloud(100)], method="marching")

    def test_an_exception_in_the_progress_callback_reaches_the_caller(self):
        class Stop(Exception):
            pass

        def progress(stage, fraction):
            raise Stop(stage)

        with self.assertRaises(Stop):
            rt.mesh([sphere_cloud()], progress=progress)


if __name__ == "__main__":
    unittest.main()
