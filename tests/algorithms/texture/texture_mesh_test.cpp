// Texturing (algorithms/texture/) on a sphere with a fine procedural checker seen by six
// cameras: the textured model reproduces the images far better than vertex colours at the
// mesh's spacing; OBJ and glb round trips; the .glb's up (root node rotation); assimp reads both
// files (when installed); bad input.
#include "algorithms/texture/texture_mesh.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "algorithms/render/rasterizer.hpp"
#include "algorithms/texture/surface_colour.hpp"
#include "io/textured_mesh_io.hpp"
#include "tests/algorithms/texture/uv_sphere.hpp"
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
    Mesh m = test::uv_sphere(rings, segments, [r](double, double) { return r; });
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

namespace {

/// The JSON chunk of a glTF binary (the first chunk, after the 12-byte header).
nlohmann::json glb_json(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::uint32_t header[5] = {};
    in.read(reinterpret_cast<char*>(header), sizeof header);
    EXPECT_EQ(header[4], 0x4E4F534Au) << "the first chunk is not JSON";
    std::string text(header[3], '\0');
    in.read(text.data(), static_cast<std::streamsize>(text.size()));
    return nlohmann::json::parse(text);
}

/// stdout of a shell command.
std::string output_of(const std::string& command) {
    std::string out;
    if (FILE* pipe = ::popen(command.c_str(), "r")) {
        char buffer[4096];
        std::size_t n;
        while ((n = std::fread(buffer, 1, sizeof buffer, pipe)) > 0) out.append(buffer, n);
        ::pclose(pipe);
    }
    return out;
}

/// The number after "<label>:" on a line of `assimp info`, or -1.
long assimp_count(const std::string& info, const std::string& label) {
    std::istringstream lines(info);
    std::string line;
    while (std::getline(lines, line))
        if (line.rfind(label + ":", 0) == 0) return std::stol(line.substr(label.size() + 1));
    return -1;
}

/// The point after "<label>" on a line of `assimp info` ("Minimum point      (x y z)").
Eigen::Vector3d assimp_point(const std::string& info, const std::string& label) {
    const std::size_t at = info.find(label);
    Eigen::Vector3d p = Eigen::Vector3d::Constant(NAN);
    if (at == std::string::npos) return p;
    std::istringstream in(info.substr(info.find('(', at) + 1));
    in >> p.x() >> p.y() >> p.z();
    return p;
}

}  // namespace

// The six cameras alternate 0.25 m above and below the sphere's equator, image rows along -z:
// the model's up is +z. A .glb stores it as a root node rotation taking it to glTF's +Y (so that
// a viewer shows the model upright) and reads it back; the vertices stay in the world frame. A
// mesh without up gets no node transform.
TEST_F(Fixture, GlbRootNodeTurnsTheCamerasUpToY) {
    ASSERT_TRUE(model_->up.has_value());
    EXPECT_NEAR(model_->up->z(), 1.0, 1e-9);
    EXPECT_NEAR((*report_)["up"][2].get<double>(), 1.0, 1e-9);
    const fs::path dir = temp_dir("glb_up");
    io::write_textured_mesh(dir / "up.glb", *model_);
    const nlohmann::json gltf = glb_json(dir / "up.glb");
    const auto& root = gltf["nodes"][gltf["scenes"][0]["nodes"][0].get<int>()];
    ASSERT_TRUE(root.contains("matrix"));
    Eigen::Matrix4d m;
    for (int i = 0; i < 16; ++i) m(i % 4, i / 4) = root["matrix"][i].get<double>();  // by column
    const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
    EXPECT_LT((r.transpose() * r - Eigen::Matrix3d::Identity()).norm(), 1e-9);
    EXPECT_NEAR(r.determinant(), 1.0, 1e-9);
    EXPECT_LT((r * Eigen::Vector3d::UnitZ() - Eigen::Vector3d::UnitY()).norm(), 1e-9);
    EXPECT_LT(m.col(3).head<3>().norm(), 1e-12) << "no translation";
    // z up becomes glTF's (x, z, -y): the smallest turn, about x.
    EXPECT_LT((r * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitX()).norm(), 1e-9);

    const TexturedMesh back = io::read_textured_mesh(dir / "up.glb");
    ASSERT_TRUE(back.up.has_value());
    EXPECT_LT((*back.up - *model_->up).norm(), 1e-9);
    ASSERT_EQ(back.faces.size(), model_->faces.size());
    for (std::size_t f = 0; f < back.faces.size(); f += 97)
        for (int j = 0; j < 3; ++j)
            EXPECT_LT(
                (back.vertices[back.faces[f][j]] - model_->vertices[model_->faces[f][j]]).norm(),
                1e-6);

    TexturedMesh plain = *model_;
    plain.up.reset();
    io::write_textured_mesh(dir / "plain.glb", plain);
    const nlohmann::json flat = glb_json(dir / "plain.glb");
    EXPECT_FALSE(flat["nodes"][0].contains("matrix"));
    EXPECT_FALSE(io::read_textured_mesh(dir / "plain.glb").up.has_value());
    EXPECT_THROW(io::gltf_up_rotation(Eigen::Vector3d::Zero()), InputError);
    // -Y up (a camera's image-up in the OpenCV frame) turns half around.
    EXPECT_LT((io::gltf_up_rotation(-Eigen::Vector3d::UnitY()) * -Eigen::Vector3d::UnitY() -
               Eigen::Vector3d::UnitY())
                  .norm(),
              1e-9);
    fs::remove_all(dir);
}

// Issue 36: "the OBJ in MeshLab and Blender (assimp reads it)". Open Asset Import (Debian's
// assimp-utils), the importer behind many tools, reads our OBJ + MTL + PNG and our .glb with
// every triangle, one material per atlas with the atlas as its diffuse (base colour) texture,
// and the .glb's root rotation (its bounds come out turned, z up to +Y). Skipped without assimp.
TEST_F(Fixture, AssimpReadsObjAndGlb) {
    if (std::system("command -v assimp >/dev/null 2>&1") != 0)
        GTEST_SKIP() << "assimp is not installed (apt-get install assimp-utils): not checked";
    const fs::path dir = temp_dir("assimp");
    io::write_textured_mesh(dir / "model.obj", *model_, "test");
    io::write_textured_mesh(dir / "model.glb", *model_, "test");
    const long faces = static_cast<long>(model_->faces.size());
    const long atlases = static_cast<long>(model_->atlases.size());

    // --raw: no post-processing, so the counts are the file's (an OBJ corner is a vertex).
    const std::string obj =
        output_of("assimp info " + (dir / "model.obj").string() + " --raw --verbose 2>&1");
    EXPECT_EQ(assimp_count(obj, "Faces"), faces) << obj;
    EXPECT_EQ(assimp_count(obj, "Vertices"), 3 * faces) << obj;
    EXPECT_EQ(assimp_count(obj, "Meshes"), atlases) << obj;
    EXPECT_GE(assimp_count(obj, "Materials"), atlases) << obj;
    EXPECT_NE(obj.find("($tex.file): [0 / "), std::string::npos) << obj;
    EXPECT_NE(obj.find("| Diffuse]"), std::string::npos) << "no diffuse texture: " << obj;
    EXPECT_NE(obj.find("'model.png'"), std::string::npos) << "texture reference: " << obj;

    const std::string glb =
        output_of("assimp info " + (dir / "model.glb").string() + " --raw --verbose 2>&1");
    EXPECT_EQ(assimp_count(glb, "Faces"), faces) << glb;
    EXPECT_EQ(assimp_count(glb, "Textures (embed.)"), atlases) << glb;
    EXPECT_EQ(assimp_count(glb, "Meshes"), atlases) << glb;
    EXPECT_NE(glb.find("| Diffuse]"), std::string::npos) << "no base colour texture: " << glb;
    // assimp applies the root node: the .glb's bounds are the OBJ's turned, (x, y, z) ->
    // (x, z, -y), so the model's up (+z, from the cameras) is +Y.
    const Eigen::Vector3d lo = assimp_point(obj, "Minimum point"),
                          hi = assimp_point(obj, "Maximum point");
    const Eigen::Vector3d turned_lo(lo.x(), lo.z(), -hi.y()), turned_hi(hi.x(), hi.z(), -lo.y());
    EXPECT_LT((assimp_point(glb, "Minimum point") - turned_lo).norm(), 1e-4) << glb;
    EXPECT_LT((assimp_point(glb, "Maximum point") - turned_hi).norm(), 1e-4) << glb;
    fs::remove_all(dir);
}
