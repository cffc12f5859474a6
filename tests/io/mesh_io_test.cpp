// Tests of single-file mesh and point-cloud I/O (io/mesh_io.hpp): round trips with colours,
// atomic writes, the real PCD/XYZ/PLY/OFF/OBJ files of shared/data.
#include "io/mesh_io.hpp"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <thread>

#include "io/output_file.hpp"
#include "io/ply_stream.hpp"
#include "tests/support/input_error.hpp"
#include "tests/support/shared_data.hpp"
#include "tests/support/temp_dir.hpp"
#include "toolkit/error.hpp"

namespace rgbd::io {
namespace {

using rgbd::test::expect_input_error;

namespace fs = std::filesystem;

fs::path temp_dir(const std::string& name) { return rgbd::test::fresh_temp_dir("io_test", name); }

using rgbd::test::shared_data;

Mesh colored_cube_mesh() {
    // An octahedron: 6 vertices, 8 faces, closed.
    Mesh m;
    std::vector<Mesh::Vertex_index> v;
    const double p[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    for (const auto& q : p) v.push_back(m.add_vertex(Point_3(q[0] / 3.0, q[1] + 0.125, q[2])));
    const int f[8][3] = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                         {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
    for (const auto& t : f) EXPECT_NE(m.add_face(v[t[0]], v[t[1]], v[t[2]]), Mesh::null_face());
    auto colors = add_vertex_colors(m);
    for (std::size_t i = 0; i < v.size(); ++i)
        colors[v[i]] = MeshColor(static_cast<unsigned char>(40 * i), 255,
                                 static_cast<unsigned char>(255 - 30 * i));
    return m;
}

void expect_same_mesh(const Mesh& a, const Mesh& b, double tol, bool colors) {
    ASSERT_EQ(a.number_of_vertices(), b.number_of_vertices());
    ASSERT_EQ(a.number_of_faces(), b.number_of_faces());
    EXPECT_TRUE(CGAL::is_closed(b));
    const auto ca = vertex_colors(a);
    const auto cb = vertex_colors(b);
    ASSERT_EQ(cb.has_value(), colors);
    auto ia = a.vertices().begin();
    for (auto vb : b.vertices()) {
        const auto va = *ia++;
        EXPECT_NEAR(CGAL::squared_distance(a.point(va), b.point(vb)), 0.0, tol * tol);
        if (colors) {
            EXPECT_EQ((*ca)[va], (*cb)[vb]);
        }
    }
}

TEST(MeshIo, PlyOffObjRoundTripWithColours) {
    const fs::path dir = temp_dir("roundtrip");
    const Mesh m = colored_cube_mesh();
    for (const char* ext : {".ply", ".off", ".obj"}) {
        const fs::path file = dir / (std::string("mesh") + ext);
        write_mesh(file, m);
        const Mesh back = read_mesh(file);
        SCOPED_TRACE(ext);
        expect_same_mesh(m, back, 0.0, /*colors=*/true);
    }
    ViewInfo view;
    view.id = 5;
    view.history = {"rgbd-mesh test"};
    write_mesh(dir / "meta.ply", m, &view);
    std::ifstream in(dir / "meta.ply", std::ios::binary);
    PlyStreamReader reader(in, "meta.ply");
    Document d;
    ASSERT_TRUE(reader.next(d));
    EXPECT_EQ(d.cloud.view.id, 5);
    EXPECT_EQ(d.cloud.view.history, view.history);
    // No temporary files left behind.
    EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 4);
    fs::remove_all(dir);
}

TEST(MeshIo, AtomicWriteLeavesNothingOnError) {
    const fs::path dir = temp_dir("atomic");
    PointCloud cloud;
    for (int i = 0; i < 1000; ++i) cloud.points.insert(Point_3(i, 0, 0));
    cloud.points.insert(Point_3(std::numeric_limits<double>::quiet_NaN(), 0, 0));
    EXPECT_THROW(write_point_cloud(dir / "bad.xyz", cloud), InputError);
    EXPECT_THROW(write_point_cloud(dir / "bad.ply", cloud), InputError);
    EXPECT_TRUE(fs::is_empty(dir));
    // An existing file is not touched by a failing write.
    { std::ofstream(dir / "keep.xyz") << "1 2 3\n"; }
    EXPECT_THROW(write_point_cloud(dir / "keep.xyz", cloud), InputError);
    EXPECT_EQ(read_point_cloud(dir / "keep.xyz").size(), 1u);
    EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
    // Missing folder -> IoError naming the file.
    try {
        write_mesh(dir / "no" / "such.ply", colored_cube_mesh());
        ADD_FAILURE() << "no error";
    } catch (const IoError& e) {
        EXPECT_NE(std::string(e.what()).find("such.ply"), std::string::npos);
    }
    fs::remove_all(dir);
}

TEST(MeshIo, SpecialFilesAreWrittenInPlace) {
    const fs::path dir = temp_dir("special");
    { std::ofstream(dir / "regular.xyz") << "1 2 3\n"; }
    EXPECT_FALSE(writes_in_place(dir / "regular.xyz"));
    EXPECT_FALSE(writes_in_place(dir));
    EXPECT_FALSE(writes_in_place(dir / "missing.ply"));
    EXPECT_TRUE(writes_in_place("/dev/null"));
    const fs::path fifo = dir / "mesh.ply";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    EXPECT_TRUE(writes_in_place(fifo));
    // A reader drains the FIFO while the mesh is written into it; the FIFO stays a FIFO.
    std::string got;
    std::thread reader([&] {
        std::ifstream in(fifo, std::ios::binary);
        got.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    });
    write_mesh(fifo, colored_cube_mesh());
    reader.join();
    EXPECT_EQ(fs::status(fifo).type(), fs::file_type::fifo);
    EXPECT_EQ(got.rfind("ply\n", 0), 0u);
    fs::remove_all(dir);
}

TEST(MeshIo, OffAndObjVariants) {
    const fs::path dir = temp_dir("variants");
    {
        std::ofstream(dir / "c.off")
            << "COFF\n# comment\n4 1 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 "
               "255\n1 1 0 0 0 255 255\n0 1 0 0.5 0.5 0.5 1.0\n4 0 1 2 3\n";
        std::ofstream(dir / "n.off")
            << "NOFF 3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n";
        std::ofstream(dir / "q.obj")
            << "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n"
               "f 1/1/1 2/1/1 3/1/1 4/1/1\nv 2 0.5 0\nf -4//1 -1//1 -3//1\n";
        std::ofstream(dir / "bad.obj") << "v 0 0 0\nv 1 0 0\nf 1 2 3\n";
        std::ofstream(dir / "bad.off") << "OFF\n3 1 0\n0 0 0\n1 0 0\n";
        std::ofstream(dir / "nan.off") << "OFF\n3 1 0\n0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n";
        std::ofstream(dir / "nofaces.obj") << "v 0 0 0\nv 1 0 0\n";
    }
    const Mesh c = read_mesh(dir / "c.off");
    EXPECT_EQ(c.number_of_faces(), 2u);
    ASSERT_TRUE(vertex_colors(c));
    EXPECT_EQ((*vertex_colors(c))[Mesh::Vertex_index(1)], MeshColor(0, 255, 0));
    EXPECT_EQ((*vertex_colors(c))[Mesh::Vertex_index(3)], MeshColor(128, 128, 128));
    const Mesh n = read_mesh(dir / "n.off");
    EXPECT_TRUE((n.property_map<Mesh::Vertex_index, Vector_3>(kVertexNormal).second));
    const Mesh q = read_mesh(dir / "q.obj");
    EXPECT_EQ(q.number_of_vertices(), 5u);
    EXPECT_TRUE(CGAL::is_valid_polygon_mesh(q));
    EXPECT_EQ(q.number_of_faces(), 3u);  // quad fan (2) + triangle with negative indices
    const auto expect_error = [](const fs::path& file, const std::string& part) {
        expect_input_error([&] { read_mesh(file); }, {file.filename().string(), part});
    };
    expect_error(dir / "bad.obj", "out of range");
    expect_error(dir / "bad.off", "truncated");
    expect_error(dir / "nan.off", "not finite");
    expect_error(dir / "nofaces.obj", "no faces");
    expect_error(dir / "missing.ply", "no such file");
    fs::remove_all(dir);
}

TEST(MeshIo, PointCloudPlyAndXyzRoundTrip) {
    const fs::path dir = temp_dir("cloud");
    PointCloud cloud;
    cloud.points.add_normal_map();
    auto colors = cloud.add_colors();
    for (int i = 0; i < 50; ++i) {
        auto idx = *cloud.points.insert(Point_3(i / 7.0, -i / 3.0, 1e-3 * i));
        cloud.points.normal(idx) = Vector_3(0, 1, 0);
        colors.set(idx, {static_cast<std::uint8_t>(i), 2, 3});
    }
    cloud.view.sensor = "s";
    write_point_cloud(dir / "c.ply", cloud);
    write_point_cloud(dir / "c.xyz", cloud);
    const PointCloud a = read_point_cloud(dir / "c.ply");
    const PointCloud b = read_point_cloud(dir / "c.xyz");
    ASSERT_EQ(a.size(), 50u);
    ASSERT_EQ(b.size(), 50u);
    EXPECT_EQ(a.view.sensor, "s");
    EXPECT_TRUE(a.has_colors());
    EXPECT_TRUE(b.points.has_normal_map());
    for (std::size_t i = 0; i < 50; ++i) {
        EXPECT_EQ(a.points.point(a.points.begin()[i]), cloud.points.point(cloud.points.begin()[i]));
        EXPECT_EQ(b.points.point(b.points.begin()[i]), cloud.points.point(cloud.points.begin()[i]));
    }
    fs::remove_all(dir);
}

TEST(MeshIo, RealPcdFiles) {
    RGBD_SKIP_WITHOUT_SHARED_DATA();
    // binary_compressed, organised 640x480 with NaN points.
    const PointCloud people = read_point_cloud(shared_data("pointclouds/pcl/five_people.pcd"));
    EXPECT_GT(people.size(), 100000u);
    EXPECT_LT(people.size(), 307200u);  // NaN points skipped
    EXPECT_TRUE(people.has_colors());
    EXPECT_EQ(people.view.grid_width, 640);
    EXPECT_EQ(people.view.grid_height, 480);
    ASSERT_TRUE(people.pixel_map());
    double z_min = 1e9, z_max = -1e9;
    std::size_t colourful = 0;
    const auto pc = people.colors();
    for (auto idx : people.points) {
        z_min = std::min(z_min, people.points.point(idx).z());
        z_max = std::max(z_max, people.points.point(idx).z());
        const Rgb c = pc.get(idx);
        if (c.r != c.g || c.g != c.b) ++colourful;
        EXPECT_LT((*people.pixel_map())[idx], 307200u);
    }
    EXPECT_GT(z_min, 0.2);  // a Kinect-class scene in metres
    EXPECT_LT(z_max, 12.0);
    EXPECT_GT(colourful, people.size() / 4);

    const PointCloud milk = read_point_cloud(shared_data("pointclouds/pcl/milk_color.pcd"));
    EXPECT_EQ(milk.size(), 13704u);

    const PointCloud bun0 = read_point_cloud(shared_data("pointclouds/pcl/bun0.pcd"));
    EXPECT_EQ(bun0.size(), 397u);
    EXPECT_TRUE(bun0.points.has_normal_map());
    const PointCloud bunny = read_point_cloud(shared_data("pointclouds/pcl/bunny.pcd"));
    EXPECT_EQ(bunny.size(), 397u);

    // binary PCD with normals and rgb.
    const PointCloud frag =
        read_point_cloud(shared_data("multiview/open3d_fragments_cloud_bin/cloud_bin_0.pcd"));
    EXPECT_EQ(frag.size(), 3903u);
    EXPECT_TRUE(frag.points.has_normal_map());
    EXPECT_TRUE(frag.has_colors());

    // ASCII with float-packed rgb and 65 m outliers (kept: the reader does not filter).
    const PointCloud uva =
        read_point_cloud(shared_data("multiview/uva_cv2_person_kinect1/0000000000.pcd"));
    EXPECT_EQ(uva.size(), 68742u);
    double uva_max = 0;
    for (auto idx : uva.points) uva_max = std::max(uva_max, uva.points.point(idx).z());
    EXPECT_GT(uva_max, 60.0);
    EXPECT_LT(uva_max, 70.0);
}

TEST(MeshIo, RealXyzPlyAndMeshes) {
    RGBD_SKIP_WITHOUT_SHARED_DATA();
    const PointCloud kitten = read_point_cloud(shared_data("pointclouds/cgal/kitten.xyz"));
    EXPECT_GT(kitten.size(), 5000u);
    EXPECT_TRUE(kitten.points.has_normal_map());
    const PointCloud sphere = read_point_cloud(shared_data("pointclouds/cgal/sphere_20k.xyz"));
    EXPECT_GT(sphere.size(), 20000u);
    EXPECT_FALSE(sphere.points.has_normal_map());
    const PointCloud oni = read_point_cloud(shared_data("pointclouds/cgal/oni.pwn"));
    EXPECT_TRUE(oni.points.has_normal_map());
    const PointCloud frag = read_point_cloud(
        shared_data("multiview/open3d_livingroom1_slac_fragments/fragment_000.ply"));
    EXPECT_EQ(frag.size(), 5028u);
    EXPECT_TRUE(frag.has_colors());
    EXPECT_TRUE(frag.points.has_normal_map());

    const Mesh planck = read_mesh(shared_data("meshes/max_planck/max-planck.obj"));
    EXPECT_EQ(planck.number_of_vertices(), 10000u);
    EXPECT_EQ(planck.number_of_faces(), 19996u);
    EXPECT_TRUE(CGAL::is_closed(planck));
    const Mesh bunny = read_mesh(shared_data("meshes/stanford_bunny/stanford-bunny.obj"));
    EXPECT_EQ(bunny.number_of_faces(), 69451u);
    const Mesh wreath = read_mesh(shared_data("meshes/danish_statues/BustManWreath_welded.ply"));
    EXPECT_EQ(wreath.number_of_faces(), 31514u);  // non-manifold faces kept (own vertices)
    EXPECT_GE(wreath.number_of_vertices(), 15757u);
    const Mesh shark = read_mesh(shared_data("meshes/cgal_with_holes/mech-holes-shark.off"));
    EXPECT_EQ(shark.number_of_vertices(), 5246u);
    EXPECT_EQ(shark.number_of_faces(), 10192u);
    const PointCloud head = read_point_cloud(shared_data("meshes/cgal_with_holes/head.off"));
    EXPECT_EQ(head.size(), 1487u);
}

}  // namespace
}  // namespace rgbd::io
