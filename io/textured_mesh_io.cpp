#include "io/textured_mesh_io.hpp"

// tinygltf compiled here; images are encoded and decoded by io/image_codec.hpp
// (io/CMakeLists.txt).
#define TINYGLTF_IMPLEMENTATION
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <tiny_gltf.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>

#include "io/capture_folder.hpp"
#include "io/image_codec.hpp"
#include "io/internal/atomic_file.hpp"
#include "io/mesh_io.hpp"
#include "io/output_file.hpp"
#include "toolkit/error.hpp"

namespace rgbd::io {
namespace fs = std::filesystem;

namespace {

std::string lower_extension(const fs::path& path) {
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return ext;
}

void check_mesh(const TexturedMesh& m, const std::string& name) {
    const long long nv = static_cast<long long>(m.vertices.size());
    RGBD_CHECK(!m.faces.empty(), name + ": the mesh has no faces");
    for (const auto& f : m.faces)
        for (const int i : f) RGBD_CHECK(i >= 0 && i < nv, name + ": face index out of range");
    if (!m.has_texture()) return;
    RGBD_CHECK(m.face_atlas.size() == m.faces.size(), name + ": face_atlas size mismatch");
    for (std::size_t f = 0; f < m.faces.size(); ++f) {
        RGBD_CHECK(m.face_atlas[f] >= 0 && m.face_atlas[f] < static_cast<int>(m.atlases.size()),
                   name + ": atlas index out of range");
        for (const int i : m.face_uvs[f])
            RGBD_CHECK(i >= 0 && i < static_cast<int>(m.uvs.size()),
                       name + ": texture coordinate index out of range");
    }
}

std::vector<std::uint8_t> encode_atlas(const cv::Mat& image, const std::string& name) {
    try {
        return encode_png(image, 3);
    } catch (const Error& e) {
        throw IoError(name + ": cannot encode the texture as PNG: " + e.what());
    }
}

// ---- OBJ ----

void write_obj(const fs::path& path, const TexturedMesh& m, const std::string& comment) {
    const auto files = textured_mesh_files(path, m);
    std::vector<fs::path> written;
    try {
        std::ostringstream mtl;
        for (std::size_t a = 0; a < m.atlases.size(); ++a) {
            const std::vector<std::uint8_t> png = encode_atlas(m.atlases[a], files[2 + a].string());
            write_bytes_atomic(files[2 + a], png.data(), png.size());
            written.push_back(files[2 + a]);
            mtl << "newmtl atlas" << a << "\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nd 1\nillum 1\nmap_Kd "
                << files[2 + a].filename().string() << "\n\n";
        }
        if (m.has_texture()) {
            write_text_atomic(files[1], mtl.str());
            written.push_back(files[1]);
        }
        internal::write_file_atomic(path, [&](std::ostream& out) {
            char line[160];
            out << "# " << (comment.empty() ? "rgbd-toolkit" : comment) << "\n";
            out << "# " << m.vertices.size() << " vertices, " << m.faces.size() << " faces\n";
            if (m.has_texture()) out << "mtllib " << files[1].filename().string() << "\n";
            const bool colours = !m.has_texture() && m.vertex_colors.size() == m.vertices.size();
            for (std::size_t i = 0; i < m.vertices.size(); ++i) {
                const auto& p = m.vertices[i];
                if (colours) {
                    const Rgb& c = m.vertex_colors[i];
                    std::snprintf(line, sizeof line, "v %.6f %.6f %.6f %.4f %.4f %.4f\n", p.x(),
                                  p.y(), p.z(), c.r / 255.0, c.g / 255.0, c.b / 255.0);
                } else {
                    std::snprintf(line, sizeof line, "v %.6f %.6f %.6f\n", p.x(), p.y(), p.z());
                }
                out << line;
            }
            if (!m.has_texture()) {
                for (const auto& f : m.faces)
                    out << "f " << f[0] + 1 << ' ' << f[1] + 1 << ' ' << f[2] + 1 << '\n';
                return;
            }
            for (const auto& uv : m.uvs) {  // OBJ: v up from the bottom of the image
                std::snprintf(line, sizeof line, "vt %.7f %.7f\n", uv.x(), 1.0 - uv.y());
                out << line;
            }
            for (std::size_t a = 0; a < m.atlases.size(); ++a) {
                out << "usemtl atlas" << a << "\n";
                for (std::size_t i = 0; i < m.faces.size(); ++i) {
                    if (m.face_atlas[i] != static_cast<int>(a)) continue;
                    const auto& f = m.faces[i];
                    const auto& t = m.face_uvs[i];
                    out << "f " << f[0] + 1 << '/' << t[0] + 1 << ' ' << f[1] + 1 << '/' << t[1] + 1
                        << ' ' << f[2] + 1 << '/' << t[2] + 1 << '\n';
                }
            }
        });
    } catch (...) {
        std::error_code ec;
        for (const auto& f : written) fs::remove(f, ec);
        throw;
    }
}

/// Index of an OBJ reference ("3", "-1"), 0-based; InputError when out of range.
int obj_index(const std::string& token, std::size_t count, const std::string& where) {
    long long i = 0;
    try {
        i = std::stoll(token);
    } catch (const std::exception&) {
        throw InputError(where + ": bad index '" + token + "'");
    }
    if (i < 0) i += static_cast<long long>(count) + 1;
    RGBD_CHECK(i >= 1 && i <= static_cast<long long>(count),
               where + ": index " + token + " out of range");
    return static_cast<int>(i - 1);
}

TexturedMesh read_obj(const fs::path& path) {
    std::ifstream in(path);
    RGBD_CHECK_AS(IoError, in.good(), path.string() + ": cannot open");
    TexturedMesh m;
    std::map<std::string, int> material_atlas;  // material name -> atlas
    int current = -1;
    bool all_textured = true;
    std::string line;
    std::size_t number = 0;
    while (std::getline(in, line)) {
        ++number;
        const std::string where = path.string() + ":" + std::to_string(number);
        std::istringstream ls(line);
        std::string key;
        ls >> key;
        if (key == "v") {
            double x, y, z, r, g, b;
            RGBD_CHECK(static_cast<bool>(ls >> x >> y >> z), where + ": bad vertex");
            m.vertices.emplace_back(x, y, z);
            if (ls >> r >> g >> b)
                m.vertex_colors.push_back(
                    {static_cast<std::uint8_t>(std::lround(std::clamp(r, 0.0, 1.0) * 255)),
                     static_cast<std::uint8_t>(std::lround(std::clamp(g, 0.0, 1.0) * 255)),
                     static_cast<std::uint8_t>(std::lround(std::clamp(b, 0.0, 1.0) * 255))});
        } else if (key == "vt") {
            double u, v;
            RGBD_CHECK(static_cast<bool>(ls >> u >> v), where + ": bad texture coordinate");
            m.uvs.emplace_back(static_cast<float>(u), static_cast<float>(1.0 - v));
        } else if (key == "mtllib") {
            std::string name;
            std::getline(ls >> std::ws, name);
            const fs::path mtl = path.parent_path() / name;
            std::ifstream min(mtl);
            RGBD_CHECK_AS(IoError, min.good(),
                          mtl.string() + ": cannot open (named by " + path.string() + ")");
            std::string ml, material;
            while (std::getline(min, ml)) {
                std::istringstream ms(ml);
                std::string k;
                ms >> k;
                if (k == "newmtl") ms >> material;
                if (k != "map_Kd") continue;
                std::string file;
                std::getline(ms >> std::ws, file);
                const fs::path image_path = mtl.parent_path() / file;
                cv::Mat image;
                try {
                    image = read_image(image_path.string(), ImageMode::kColor);
                } catch (const IoError& e) {
                    throw IoError(std::string(e.what()) + " (the texture named by " + mtl.string() +
                                  ")");
                }
                material_atlas[material] = static_cast<int>(m.atlases.size());
                m.atlases.push_back(image);
            }
        } else if (key == "usemtl") {
            std::string name;
            ls >> name;
            const auto it = material_atlas.find(name);
            current = it == material_atlas.end() ? -1 : it->second;
        } else if (key == "f") {
            std::vector<int> vs, ts;
            std::string token;
            while (ls >> token) {
                const auto slash = token.find('/');
                vs.push_back(obj_index(token.substr(0, slash), m.vertices.size(), where));
                const std::string rest = slash == std::string::npos ? "" : token.substr(slash + 1);
                const std::string vt = rest.substr(0, rest.find('/'));
                if (vt.empty())
                    ts.push_back(-1);
                else
                    ts.push_back(obj_index(vt, m.uvs.size(), where));
            }
            RGBD_CHECK(vs.size() >= 3, where + ": a face needs at least 3 vertices");
            for (std::size_t j = 1; j + 1 < vs.size(); ++j) {
                m.faces.push_back({vs[0], vs[j], vs[j + 1]});
                m.face_uvs.push_back({ts[0], ts[j], ts[j + 1]});
                m.face_atlas.push_back(current);
                all_textured =
                    all_textured && current >= 0 && ts[0] >= 0 && ts[j] >= 0 && ts[j + 1] >= 0;
            }
        }
    }
    RGBD_CHECK(!m.faces.empty(), path.string() + ": no faces");
    if (!all_textured || m.atlases.empty()) {
        m.face_uvs.clear();
        m.face_atlas.clear();
        m.atlases.clear();
    }
    if (m.vertex_colors.size() != m.vertices.size()) m.vertex_colors.clear();
    return m;
}

// ---- glTF binary ----

/// Appends `bytes` to the buffer (4-byte aligned) as a buffer view; returns its index.
int add_view(tinygltf::Model& model, const void* bytes, std::size_t size, int target) {
    auto& data = model.buffers[0].data;
    while (data.size() % 4) data.push_back(0);
    tinygltf::BufferView view;
    view.buffer = 0;
    view.byteOffset = data.size();
    view.byteLength = size;
    if (target) view.target = target;
    const auto* p = static_cast<const unsigned char*>(bytes);
    data.insert(data.end(), p, p + size);
    model.bufferViews.push_back(view);
    return static_cast<int>(model.bufferViews.size()) - 1;
}

int add_accessor(tinygltf::Model& model, int view, int component, int type, std::size_t count,
                 bool normalized = false) {
    tinygltf::Accessor a;
    a.bufferView = view;
    a.componentType = component;
    a.type = type;
    a.count = count;
    a.normalized = normalized;
    model.accessors.push_back(a);
    return static_cast<int>(model.accessors.size()) - 1;
}

void write_glb(const fs::path& path, const TexturedMesh& m, const std::string& comment) {
    tinygltf::Model model;
    model.asset.version = "2.0";
    model.asset.generator = comment.empty() ? "rgbd-toolkit" : comment;
    model.buffers.resize(1);
    const bool textured = m.has_texture();
    // glTF vertices carry one texture coordinate: one vertex per (position, uv) pair.
    std::vector<float> positions, texcoords;
    std::vector<std::uint8_t> colours;
    std::vector<std::vector<std::uint32_t>> indices(textured ? m.atlases.size() : 1);
    if (textured) {
        std::vector<int> of_uv(m.uvs.size(), -1);
        std::map<std::pair<int, int>, int> of_pair;  // flat cells share a uv between vertices
        for (std::size_t f = 0; f < m.faces.size(); ++f)
            for (int j = 0; j < 3; ++j) {
                const int v = m.faces[f][j], t = m.face_uvs[f][j];
                auto [it, fresh] =
                    of_pair.try_emplace({v, t}, static_cast<int>(positions.size() / 3));
                if (fresh) {
                    for (int c = 0; c < 3; ++c)
                        positions.push_back(static_cast<float>(m.vertices[v][c]));
                    texcoords.push_back(m.uvs[t].x());
                    texcoords.push_back(m.uvs[t].y());
                }
                indices[m.face_atlas[f]].push_back(static_cast<std::uint32_t>(it->second));
            }
    } else {
        for (const auto& p : m.vertices)
            for (int c = 0; c < 3; ++c) positions.push_back(static_cast<float>(p[c]));
        for (const auto& c : m.vertex_colors) colours.insert(colours.end(), {c.r, c.g, c.b, 255});
        for (const auto& f : m.faces)
            for (const int v : f) indices[0].push_back(static_cast<std::uint32_t>(v));
    }
    const std::size_t count = positions.size() / 3;
    const int pos = add_accessor(
        model,
        add_view(model, positions.data(), positions.size() * 4, TINYGLTF_TARGET_ARRAY_BUFFER),
        TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, count);
    std::vector<double> lo(3, 1e300), hi(3, -1e300);
    for (std::size_t i = 0; i < positions.size(); ++i) {
        lo[i % 3] = std::min(lo[i % 3], static_cast<double>(positions[i]));
        hi[i % 3] = std::max(hi[i % 3], static_cast<double>(positions[i]));
    }
    model.accessors[pos].minValues = lo;
    model.accessors[pos].maxValues = hi;
    int uv = -1, colour = -1;
    if (textured)
        uv = add_accessor(
            model,
            add_view(model, texcoords.data(), texcoords.size() * 4, TINYGLTF_TARGET_ARRAY_BUFFER),
            TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC2, count);
    if (!colours.empty())
        colour = add_accessor(
            model, add_view(model, colours.data(), colours.size(), TINYGLTF_TARGET_ARRAY_BUFFER),
            TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_TYPE_VEC4, count, /*normalized=*/true);
    tinygltf::Mesh mesh;
    tinygltf::Sampler sampler;
    sampler.magFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
    sampler.minFilter = TINYGLTF_TEXTURE_FILTER_LINEAR_MIPMAP_LINEAR;
    sampler.wrapS = sampler.wrapT = TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE;
    model.samplers.push_back(sampler);
    for (std::size_t a = 0; a < indices.size(); ++a) {
        if (indices[a].empty()) continue;
        tinygltf::Primitive prim;
        prim.mode = TINYGLTF_MODE_TRIANGLES;
        prim.attributes["POSITION"] = pos;
        if (uv >= 0) prim.attributes["TEXCOORD_0"] = uv;
        if (colour >= 0) prim.attributes["COLOR_0"] = colour;
        prim.indices = add_accessor(model,
                                    add_view(model, indices[a].data(), indices[a].size() * 4,
                                             TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER),
                                    TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR,
                                    indices[a].size());
        tinygltf::Material material;
        material.name = "atlas" + std::to_string(a);
        material.pbrMetallicRoughness.metallicFactor = 0.0;
        material.pbrMetallicRoughness.roughnessFactor = 1.0;
        material.doubleSided = false;
        // The colour is measured light: shown unlit where the viewer supports it.
        material.extensions["KHR_materials_unlit"] = tinygltf::Value(tinygltf::Value::Object());
        if (textured) {
            const std::vector<std::uint8_t> png =
                encode_atlas(m.atlases[a], path.string() + " (atlas " + std::to_string(a) + ")");
            tinygltf::Image image;
            image.mimeType = "image/png";
            image.bufferView = add_view(model, png.data(), png.size(), 0);
            model.images.push_back(image);
            tinygltf::Texture texture;
            texture.sampler = 0;
            texture.source = static_cast<int>(model.images.size()) - 1;
            model.textures.push_back(texture);
            material.pbrMetallicRoughness.baseColorTexture.index =
                static_cast<int>(model.textures.size()) - 1;
        }
        model.materials.push_back(material);
        prim.material = static_cast<int>(model.materials.size()) - 1;
        mesh.primitives.push_back(prim);
    }
    model.extensionsUsed.push_back("KHR_materials_unlit");
    model.meshes.push_back(mesh);
    tinygltf::Node node;
    node.mesh = 0;
    if (m.up) {  // column-major 4 x 4, no translation: vertices stay in the world frame
        const Eigen::Matrix3d r = gltf_up_rotation(*m.up);
        node.matrix.assign(16, 0.0);
        for (int c = 0; c < 3; ++c)
            for (int row = 0; row < 3; ++row) node.matrix[4 * c + row] = r(row, c);
        node.matrix[15] = 1.0;
    }
    model.nodes.push_back(node);
    tinygltf::Scene scene;
    scene.nodes.push_back(0);
    model.scenes.push_back(scene);
    model.defaultScene = 0;
    internal::write_file_atomic(path, [&](std::ostream& out) {
        tinygltf::TinyGLTF gltf;
        RGBD_CHECK_AS(IoError,
                      gltf.WriteGltfSceneToStream(&model, out, /*prettyPrint=*/false,
                                                  /*writeBinary=*/true),
                      path.string() + ": cannot write the glTF binary");
    });
}

/// tinygltf image loader: decodes PNG/JPEG (io/image_codec.hpp; BGR, 3 channels).
bool load_gltf_image(tinygltf::Image* image, const int, std::string* err, std::string*, int, int,
                     const unsigned char* bytes, int size, void*) {
    cv::Mat bgr;
    try {
        bgr = decode_image(bytes, size < 0 ? 0 : static_cast<std::size_t>(size), ImageMode::kColor,
                           "an embedded image");
    } catch (const IoError& e) {
        if (err) *err = e.what();
        return false;
    }
    image->width = bgr.cols;
    image->height = bgr.rows;
    image->component = 3;
    image->bits = 8;
    image->pixel_type = TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
    image->image.assign(bgr.data, bgr.data + bgr.total() * 3);
    return true;
}

/// Element `i` of an accessor as doubles (float, or normalised unsigned byte/short).
std::vector<double> element(const tinygltf::Model& model, const tinygltf::Accessor& a,
                            std::size_t i, const std::string& name) {
    RGBD_CHECK(a.bufferView >= 0 && a.bufferView < static_cast<int>(model.bufferViews.size()),
               name + ": accessor without buffer view");
    const auto& view = model.bufferViews[a.bufferView];
    const auto& data = model.buffers.at(view.buffer).data;
    const int n = tinygltf::GetNumComponentsInType(a.type);
    const int size = tinygltf::GetComponentSizeInBytes(a.componentType);
    const std::size_t stride =
        view.byteStride ? view.byteStride : static_cast<std::size_t>(n * size);
    const std::size_t at = view.byteOffset + a.byteOffset + i * stride;
    RGBD_CHECK(n > 0 && size > 0 && at + n * size <= data.size(),
               name + ": accessor out of bounds");
    std::vector<double> out(n);
    for (int c = 0; c < n; ++c) {
        const unsigned char* p = data.data() + at + c * size;
        switch (a.componentType) {
            case TINYGLTF_COMPONENT_TYPE_FLOAT: {
                float v;
                std::memcpy(&v, p, 4);
                out[c] = v;
                break;
            }
            case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
                out[c] = a.normalized ? *p / 255.0 : *p;
                break;
            case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
                std::uint16_t v;
                std::memcpy(&v, p, 2);
                out[c] = a.normalized ? v / 65535.0 : v;
                break;
            }
            case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
                std::uint32_t v;
                std::memcpy(&v, p, 4);
                out[c] = v;
                break;
            }
            default:
                throw InputError(name + ": unsupported accessor component type");
        }
    }
    return out;
}

/// The direction the root node of the default scene turns to +Y, when its transform is a
/// rotation (matrix without translation or scale, or a quaternion alone); else none.
std::optional<Eigen::Vector3d> root_up(const tinygltf::Model& model) {
    const int s = model.defaultScene >= 0 ? model.defaultScene : 0;
    if (s >= static_cast<int>(model.scenes.size()) || model.scenes[s].nodes.empty()) return {};
    const tinygltf::Node& node = model.nodes.at(model.scenes[s].nodes.front());
    Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
    if (node.matrix.size() == 16) {
        for (int c = 0; c < 3; ++c)
            for (int row = 0; row < 3; ++row) r(row, c) = node.matrix[4 * c + row];
        const bool moved =
            std::abs(node.matrix[12]) + std::abs(node.matrix[13]) + std::abs(node.matrix[14]) >
                1e-9 ||
            node.matrix[3] != 0 || node.matrix[7] != 0 || node.matrix[11] != 0 ||
            node.matrix[15] != 1;
        if (moved || !r.allFinite() || !(r.transpose() * r).isIdentity(1e-6) ||
            std::abs(r.determinant() - 1) > 1e-6)
            return {};
    } else if (node.rotation.size() == 4 && node.translation.empty() && node.scale.empty()) {
        const Eigen::Quaterniond q(node.rotation[3], node.rotation[0], node.rotation[1],
                                   node.rotation[2]);
        if (!(std::abs(q.norm() - 1) < 1e-6)) return {};
        r = q.toRotationMatrix();
    } else {
        return {};
    }
    return r.transpose() * Eigen::Vector3d::UnitY();
}

TexturedMesh read_glb(const fs::path& path) {
    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(load_gltf_image, nullptr);
    tinygltf::Model model;
    std::string err, warn;
    const std::string name = path.string();
    std::ifstream in(path, std::ios::binary);
    RGBD_CHECK_AS(IoError, in.good(), name + ": cannot open");
    const std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)),
                                           std::istreambuf_iterator<char>());
    RGBD_CHECK(
        !bytes.empty() && loader.LoadBinaryFromMemory(&model, &err, &warn, bytes.data(),
                                                      static_cast<unsigned int>(bytes.size())),
        name + ": not a readable glTF binary" + (err.empty() ? "" : " (" + err + ")"));
    TexturedMesh m;
    std::map<int, int> atlas_of_image;
    bool textured = true;
    for (const auto& mesh : model.meshes)
        for (const auto& prim : mesh.primitives) {
            RGBD_CHECK(prim.mode == TINYGLTF_MODE_TRIANGLES || prim.mode == -1,
                       name + ": only triangle primitives are supported");
            RGBD_CHECK(prim.attributes.count("POSITION"), name + ": primitive without POSITION");
            const auto& pa = model.accessors.at(prim.attributes.at("POSITION"));
            const int base = static_cast<int>(m.vertices.size());
            for (std::size_t i = 0; i < pa.count; ++i) {
                const auto p = element(model, pa, i, name);
                m.vertices.emplace_back(p[0], p[1], p[2]);
            }
            if (prim.attributes.count("COLOR_0")) {
                const auto& ca = model.accessors.at(prim.attributes.at("COLOR_0"));
                for (std::size_t i = 0; i < ca.count; ++i) {
                    const auto c = element(model, ca, i, name);
                    m.vertex_colors.push_back({static_cast<std::uint8_t>(std::lround(c[0] * 255)),
                                               static_cast<std::uint8_t>(std::lround(c[1] * 255)),
                                               static_cast<std::uint8_t>(std::lround(c[2] * 255))});
                }
            }
            int atlas = -1;
            if (prim.material >= 0 && prim.attributes.count("TEXCOORD_0")) {
                const int tex =
                    model.materials.at(prim.material).pbrMetallicRoughness.baseColorTexture.index;
                if (tex >= 0) {
                    const int source = model.textures.at(tex).source;
                    auto [it, fresh] =
                        atlas_of_image.try_emplace(source, static_cast<int>(m.atlases.size()));
                    if (fresh) {
                        const auto& img = model.images.at(source);
                        RGBD_CHECK(img.component == 3 && !img.image.empty(),
                                   name + ": texture image not decoded");
                        m.atlases.push_back(cv::Mat(img.height, img.width, CV_8UC3,
                                                    const_cast<unsigned char*>(img.image.data()))
                                                .clone());
                    }
                    atlas = it->second;
                    const auto& ta = model.accessors.at(prim.attributes.at("TEXCOORD_0"));
                    RGBD_CHECK(ta.count == pa.count,
                               name + ": TEXCOORD_0 and POSITION counts differ");
                    for (std::size_t i = 0; i < ta.count; ++i) {
                        const auto t = element(model, ta, i, name);
                        m.uvs.emplace_back(static_cast<float>(t[0]), static_cast<float>(t[1]));
                    }
                }
            }
            textured = textured && atlas >= 0;
            RGBD_CHECK(prim.indices >= 0, name + ": primitives without indices are not supported");
            const auto& ia = model.accessors.at(prim.indices);
            const int uv_base =
                static_cast<int>(m.uvs.size()) - (atlas >= 0 ? static_cast<int>(pa.count) : 0);
            for (std::size_t i = 0; i + 2 < ia.count; i += 3) {
                std::array<int, 3> f;
                for (int j = 0; j < 3; ++j) {
                    const auto idx = static_cast<int>(element(model, ia, i + j, name)[0]);
                    RGBD_CHECK(idx >= 0 && idx < static_cast<int>(pa.count),
                               name + ": index out of range");
                    f[j] = idx;
                }
                m.faces.push_back({base + f[0], base + f[1], base + f[2]});
                m.face_uvs.push_back({uv_base + f[0], uv_base + f[1], uv_base + f[2]});
                m.face_atlas.push_back(atlas);
            }
        }
    RGBD_CHECK(!m.faces.empty(), name + ": no triangles");
    m.up = root_up(model);
    if (!textured || m.atlases.empty()) {
        m.face_uvs.clear();
        m.face_atlas.clear();
        m.atlases.clear();
        m.uvs.clear();
    }
    if (m.vertex_colors.size() != m.vertices.size()) m.vertex_colors.clear();
    return m;
}

}  // namespace

Eigen::Matrix3d gltf_up_rotation(const Eigen::Vector3d& up) {
    RGBD_CHECK(up.allFinite() && up.norm() > 0, "the up direction must be finite and non-zero");
    return Eigen::Quaterniond::FromTwoVectors(up.normalized(), Eigen::Vector3d::UnitY())
        .toRotationMatrix();
}

bool is_textured_format(const fs::path& path) {
    const std::string ext = lower_extension(path);
    return ext == ".obj" || ext == ".glb";
}

std::vector<fs::path> textured_mesh_files(const fs::path& path, const TexturedMesh& mesh) {
    std::vector<fs::path> files = {path};
    if (lower_extension(path) != ".obj") return files;
    files.push_back(fs::path(path).replace_extension(".mtl"));
    const std::string stem = fs::path(path).replace_extension().string();
    for (std::size_t a = 0; a < mesh.atlases.size(); ++a)
        files.push_back(mesh.atlases.size() == 1
                            ? fs::path(stem + ".png")
                            : fs::path(stem + "_" + std::to_string(a) + ".png"));
    return files;
}

void write_textured_mesh(const fs::path& path, const TexturedMesh& mesh,
                         const std::string& comment) {
    check_output_path(path);
    check_mesh(mesh, path.string());
    const std::string ext = lower_extension(path);
    if (ext == ".obj")
        write_obj(path, mesh, comment);
    else if (ext == ".glb")
        write_glb(path, mesh, comment);
    else
        throw InputError(path.string() + ": a textured model is written as .obj or .glb");
}

TexturedMesh read_textured_mesh(const fs::path& path) {
    RGBD_CHECK_AS(IoError, fs::exists(path), path.string() + ": no such file");
    const std::string ext = lower_extension(path);
    if (ext == ".obj") return read_obj(path);
    if (ext == ".glb") return read_glb(path);
    try {
        return untextured(read_mesh(path));
    } catch (const InputError& e) {
        const std::string what = e.what();
        if (what.rfind(path.string(), 0) == 0) throw;
        throw InputError(path.string() + ": " + what);
    }
}

}  // namespace rgbd::io
