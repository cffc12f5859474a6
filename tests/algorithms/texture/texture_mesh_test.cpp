// Texturing (algorithms/texture/) on a sphere with a fine procedural checker seen by six
// cameras: the textured model reproduces the images far better than vertex colours at the
// mesh's spacing; OBJ and glb round trips; bad input.
#include "algorithms/texture/texture_mesh.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "algorithms/render/rasterizer.hpp"
#include "algorithms/texture/surface_colour.hpp"
#include "io/textured_mesh_io.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;
namespace fs = std::filesystem;

namespace {

/// 1 cm checker of red and white (in 3D), finer than the mesh's ~2.5 cm edges.
Rgb checker(const Eigen::Vector3d& p) {
    const int k = static_cast<int>(std::floor(p.x() / 0.01) + std::floor(p.y() / 0.01) +
                                   std::floor(p.z() / 0.01));
    return (k & 1) ? Rgb{200, 40, 40} : Rgb{240, 240, 240};
}

/// A UV sphere of radius r at the origin with vertex colours from the checker.
Mesh sphere(double r, int rings, int segments) {
    Mesh m;
    std::vector<Mesh::Vertex_index> v;
    const auto top = m.add_vertex(Point_3(0, 0, r));
    for (int i = 1; i < rings; ++i)
        for (int j = 0; j < segments; ++j) {
            const double th = M_PI * i / rings, ph = 2 * M_PI * j / segments;
            v.push_back(m.add_vertex(Point_3(r * std::sin(th) * std::cos(ph),
                                             r * std::sin(th) * std::sin(ph), r * std::cos(th))));
        }
    const auto bottom = m.add_vertex(Point_3(0, 0, -r));
    auto at = [&](int i, int j) { return v[(i - 1) * segments + (j % segments)]; };
    for (int j = 0; j < segments; ++j) {
        m.add_face(top, at(1, j), at(1, j + 1));
        m.add_face(bottom, at(rings - 1, j + 1), at(rings - 1, j));
    }
    for (int i = 1; i + 1 < rings; ++i)
        for (int j = 0; j < segments; ++j) {
            m.add_face(at(i, j), at(i + 1, j), at(i + 1, j + 1));
            m.add_face(at(i, j), at(i + 1, j + 1), at(i, j + 1));
        }
    auto colours = add_vertex_colors(m);
    for (const auto vi : m.vertices()) {
        const auto& p = m.point(vi);
        const Rgb c = checker({p.x(), p.y(), p.z()});
        colours[vi] = MeshColor(c.r, c.g, c.b);
    }
    return m;
}

/// A camera at `eye` looking at the origin (z forward, y down), world_from_camera.
Pose look_at(const Eigen::Vector3d& eye) {
    const Eigen::Vector3d z = (-eye).normalized();
    Eigen::Vector3d x = z.cross(Eigen::Vector3d(0, 0, 1));
    if (x.norm() < 1e-6) x = Eigen::Vector3d(1, 0, 0);
    x.normalize();
    const Eigen::Vector3d y = z.cross(x);
    Pose pose = Pose::Identity();
    pose.linear() << x, y, z;
    pose.translation() = eye;
    return pose;
}

std::vector<texture::TextureView> ring_views(const Mesh& mesh) {
    const render::RenderScene scene(mesh);
    PinholeIntrinsics k{
        .width = 640, .height = 480, .fx = 700, .fy = 700, .cx = 319.5, .cy = 239.5};
    std::vector<texture::TextureView> views;
    for (int i = 0; i < 6; ++i) {
        const double a = 2 * M_PI * i / 6;
        const Eigen::Vector3d eye(0.7 * std::cos(a), 0.7 * std::sin(a), i % 2 ? 0.25 : -0.25);
        texture::TextureView v;
        v.intrinsics = k;
        v.world_from_camera = look_at(eye);
        // The true surface colour (of the exact sphere point under the pixel's facet).
        v.image = render::render_color(
            scene, k, v.world_from_camera, [](const Eigen::Vector3d& p, int) { return checker(p); },
            Rgb{0, 0, 0});
        v.name = "camera " + std::to_string(i);
        views.push_back(std::move(v));
    }
    return views;
}

struct Fixture : ::testing::Test {
    static void SetUpTestSuite() {
        mesh_ = new Mesh(sphere(0.15, 24, 48));
        views_ = new std::vector<texture::TextureView>(ring_views(*mesh_));
        report_ = new Report();
        model_ = new TexturedMesh(
            texture::texture_mesh(*mesh_, *views_, texture::TextureOptions{}, *report_));
    }
    static void TearDownTestSuite() {
        delete mesh_;
        delete views_;
        delete report_;
        delete model_;
    }
    static Mesh* mesh_;
    static std::vector<texture::TextureView>* views_;
    static Report* report_;
    static TexturedMesh* model_;
};
Mesh* Fixture::mesh_ = nullptr;
std::vector<texture::TextureView>* Fixture::views_ = nullptr;
Report* Fixture::report_ = nullptr;
TexturedMesh* Fixture::model_ = nullptr;

fs::path temp_dir(const std::string& name) {
    const fs::path dir = fs::temp_directory_path() /
                         ("rgbd_texture_test_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

}  // namespace

TEST_F(Fixture, TextureBeatsVertexColoursByAClearMargin) {
    ASSERT_TRUE(model_->has_texture());
    const auto textured = texture::surface_colour_error(*model_, *views_);
    const auto plain = texture::surface_colour_error(untextured(*mesh_), *views_);
    EXPECT_GT(textured.pixels, 100000u);
    // Vertex colours at 2.5 cm spacing cannot show a 1 cm checker; the texture can.
    EXPECT_GT(textured.psnr_db, plain.psnr_db + 6.0)
        << "textured " << textured.psnr_db << " dB, vertex colours " << plain.psnr_db << " dB";
    EXPECT_LT(textured.mae, 0.5 * plain.mae);
    // The cameras are alike: the adjustment leaves gains near 1.
    for (const auto& v : (*report_)["adjust"]["views"])
        for (const auto& g : v["gain_rgb"]) EXPECT_NEAR(g.get<double>(), 1.0, 0.05);
    // A ring tilted up and down sees the whole sphere but the poles' tiny caps.
    EXPECT_LT((*report_)["selection"]["unseen_faces"].get<std::size_t>(),
              model_->faces.size() / 20);
    EXPECT_LT((*report_)["atlas"]["charts"].get<std::size_t>(), model_->faces.size() / 10);
}

TEST_F(Fixture, SmoothnessMakesFewerCharts) {
    texture::TextureOptions rough;
    rough.selection.smoothness = 0;
    Report r;
    texture::texture_mesh(*mesh_, *views_, rough, r);
    EXPECT_LT((*report_)["atlas"]["charts"].get<std::size_t>(),
              r["atlas"]["charts"].get<std::size_t>());
}

TEST_F(Fixture, ObjRoundTrip) {
    const fs::path dir = temp_dir("obj");
    const fs::path obj = dir / "model.obj";
    io::write_textured_mesh(obj, *model_, "test");
    ASSERT_TRUE(fs::exists(dir / "model.mtl"));
    ASSERT_TRUE(fs::exists(dir / "model.png"));
    std::ifstream mtl(dir / "model.mtl");
    std::stringstream text;
    text << mtl.rdbuf();
    EXPECT_NE(text.str().find("map_Kd model.png"), std::string::npos);
    std::size_t v = 0, vt = 0, f = 0;
    std::ifstream in(obj);
    std::string line;
    while (std::getline(in, line)) {
        v += line.rfind("v ", 0) == 0;
        vt += line.rfind("vt ", 0) == 0;
        f += line.rfind("f ", 0) == 0;
    }
    EXPECT_EQ(v, model_->vertices.size());
    EXPECT_EQ(vt, model_->uvs.size());
    EXPECT_EQ(f, model_->faces.size());
    const TexturedMesh back = io::read_textured_mesh(obj);
    ASSERT_TRUE(back.has_texture());
    EXPECT_EQ(back.faces.size(), model_->faces.size());
    for (const auto& uv : back.uvs) {
        EXPECT_GE(uv.x(), 0.0f);
        EXPECT_LE(uv.x(), 1.0f);
        EXPECT_GE(uv.y(), 0.0f);
        EXPECT_LE(uv.y(), 1.0f);
    }
    const auto a = texture::surface_colour_error(*model_, *views_);
    const auto b = texture::surface_colour_error(back, *views_);
    EXPECT_NEAR(a.psnr_db, b.psnr_db, 0.05);
    fs::remove_all(dir);
}

TEST_F(Fixture, GlbRoundTrip) {
    const fs::path dir = temp_dir("glb");
    const fs::path glb = dir / "model.glb";
    io::write_textured_mesh(glb, *model_, "test");
    std::ifstream in(glb, std::ios::binary);
    char magic[4] = {};
    in.read(magic, 4);
    EXPECT_EQ(std::string(magic, 4), "glTF");
    const TexturedMesh back = io::read_textured_mesh(glb);  // tinygltf
    ASSERT_TRUE(back.has_texture());
    EXPECT_EQ(back.faces.size(), model_->faces.size());
    ASSERT_EQ(back.atlases.size(), model_->atlases.size());
    EXPECT_EQ(cv::norm(back.atlases[0], model_->atlases[0], cv::NORM_INF), 0.0);
    const auto a = texture::surface_colour_error(*model_, *views_);
    const auto b = texture::surface_colour_error(back, *views_);
    EXPECT_NEAR(a.psnr_db, b.psnr_db, 0.05);
    fs::remove_all(dir);
}

TEST_F(Fixture, SmallAtlasLimitScalesOrSplits) {
    texture::TextureOptions small;
    small.atlas.max_size = 256;
    Report r;
    const TexturedMesh m = texture::texture_mesh(*mesh_, *views_, small, r);
    for (const auto& a : m.atlases) {
        EXPECT_LE(a.cols, 256);
        EXPECT_LE(a.rows, 256);
    }
    EXPECT_TRUE(r["atlas"]["texel_scale"].get<double>() < 1.0 || m.atlases.size() > 1);
}

TEST_F(Fixture, MeshNoCameraSeesIsAnError) {
    Mesh far = *mesh_;
    for (const auto v : far.vertices()) {
        const auto& p = far.point(v);
        far.point(v) = Point_3(p.x() + 50, p.y(), p.z());
    }
    Report r;
    try {
        texture::texture_mesh(far, *views_, {}, r);
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("no face of the mesh is seen"), std::string::npos);
    }
}

TEST_F(Fixture, WrongImageSizeIsAnError) {
    auto views = *views_;
    views[2].image = cv::Mat(100, 100, CV_8UC3);
    Report r;
    EXPECT_THROW(texture::texture_mesh(*mesh_, views, {}, r), InputError);
    views[2].image = cv::Mat();
    EXPECT_THROW(texture::texture_mesh(*mesh_, views, {}, r), InputError);
}

TEST_F(Fixture, UnwritableOutputLeavesNoFile) {
    const fs::path dir = temp_dir("missing");
    const fs::path obj = dir / "no" / "model.obj";
    EXPECT_THROW(io::write_textured_mesh(obj, *model_), IoError);
    EXPECT_FALSE(fs::exists(dir / "no"));
    fs::remove_all(dir);
}
