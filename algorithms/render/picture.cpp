#include "algorithms/render/picture.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <random>

#include "algorithms/internal/cell_grid.hpp"
#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/render/rasterizer.hpp"
#include "toolkit/enum_names.hpp"
#include "toolkit/error.hpp"
#include "toolkit/order_statistics.hpp"

namespace rgbd::render {
namespace {

constexpr double kPi = 3.14159265358979323846;

/// count_quantile of a copy of `v` (the callers keep their order).
double quantile(std::vector<double> v, double q) { return count_quantile(v, q); }

/// The turbo colour map as 256 RGB entries.
const std::array<Rgb, 256>& turbo() {
    static const std::array<Rgb, 256> lut = [] {
        cv::Mat ramp(1, 256, CV_8UC1);
        for (int i = 0; i < 256; ++i) ramp.at<std::uint8_t>(0, i) = static_cast<std::uint8_t>(i);
        cv::Mat bgr;
        cv::applyColorMap(ramp, bgr, cv::COLORMAP_TURBO);
        std::array<Rgb, 256> out;
        for (int i = 0; i < 256; ++i) {
            const cv::Vec3b c = bgr.at<cv::Vec3b>(0, i);
            out[i] = {c[2], c[1], c[0]};
        }
        return out;
    }();
    return lut;
}

Rgb scaled(Rgb c, double f) {
    auto s = [f](std::uint8_t v) {
        return static_cast<std::uint8_t>(std::clamp(std::lround(v * f), 0L, 255L));
    };
    return {s(c.r), s(c.g), s(c.b)};
}

std::uint8_t grey(double intensity) {
    return static_cast<std::uint8_t>(std::clamp(std::lround(255.0 * intensity), 0L, 255L));
}

/// Light direction (towards the light) in the world: above-left of the camera.
Eigen::Vector3d light_direction(const Pose& world_from_camera) {
    const Eigen::Vector3d in_camera(-0.35, -0.5, -1.0);  // left, up (y down), towards viewer
    return (world_from_camera.linear() * in_camera).normalized();
}

double lambert(const Eigen::Vector3d& n, const Eigen::Vector3d& light) {
    const double len = n.norm();
    if (!(len > 0)) return 0.5;
    return std::abs(n.dot(light)) / len;  // two-sided: Poisson and scans mix orientations
}

/// A colour-bar label: 3 significant digits (%.3g).
std::string bar_label(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.3g", v);
    return buf;
}

/// Appends the colour bar strip to `model` (the model area) and fills the picture's bar fields.
void add_color_bar(Picture& pic, const cv::Mat& model, const PictureOptions& options) {
    const int h = model.rows;
    const int strip = std::max(64, model.cols / 6);
    cv::Mat out(h, model.cols + strip, CV_8UC3,
                cv::Scalar(options.background.b, options.background.g, options.background.r));
    model.copyTo(out(cv::Rect(0, 0, model.cols, h)));
    const int bar_w = std::max(8, strip / 5);
    const int top = std::max(4, h / 10), bottom = h - std::max(4, h / 10);
    const int x0 = model.cols + std::max(4, strip / 10);
    const cv::Rect bar(x0, top, bar_w, bottom - top);
    const auto& lut = turbo();
    for (int y = bar.y; y < bar.y + bar.height; ++y) {
        const double t = 1.0 - double(y - bar.y) / double(std::max(1, bar.height - 1));
        const Rgb c = lut[static_cast<std::size_t>(std::lround(t * 255.0))];
        for (int x = bar.x; x < bar.x + bar.width; ++x)
            out.at<cv::Vec3b>(y, x) = cv::Vec3b(c.b, c.g, c.r);
    }
    const double font = std::clamp(h / 900.0, 0.35, 1.2);
    const int thick = font > 0.7 ? 2 : 1;
    const cv::Scalar ink(40, 40, 40);
    const int tx = bar.x + bar.width + 4;
    cv::putText(out, bar_label(pic.scalar_max * options.scalar_display_scale),
                cv::Point(tx, bar.y + static_cast<int>(10 * font)), cv::FONT_HERSHEY_SIMPLEX, font,
                ink, thick, cv::LINE_AA);
    cv::putText(out, bar_label(pic.scalar_min * options.scalar_display_scale),
                cv::Point(tx, bar.y + bar.height), cv::FONT_HERSHEY_SIMPLEX, font, ink, thick,
                cv::LINE_AA);
    if (!options.scalar_label.empty())
        cv::putText(out, options.scalar_label, cv::Point(model.cols + 2, std::max(12, top / 2)),
                    cv::FONT_HERSHEY_SIMPLEX, font * 0.9, ink, thick, cv::LINE_AA);
    pic.color_bar = bar;
    pic.image = out;
}

/// The colour of a CV_8UC3 BGR image at texture coordinates `uv` ([0, 1], origin at the
/// top-left corner of the image), bilinear between the texel centres, clamped at the border.
Rgb sample_bilinear(const cv::Mat& image, const Eigen::Vector2f& uv) {
    const float x = std::clamp(uv.x() * image.cols - 0.5f, 0.0f, float(image.cols - 1));
    const float y = std::clamp(uv.y() * image.rows - 0.5f, 0.0f, float(image.rows - 1));
    const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
    const int x1 = std::min(x0 + 1, image.cols - 1), y1 = std::min(y0 + 1, image.rows - 1);
    const float fx = x - x0, fy = y - y0;
    const cv::Vec3b a = image.at<cv::Vec3b>(y0, x0), b = image.at<cv::Vec3b>(y0, x1),
                    c = image.at<cv::Vec3b>(y1, x0), d = image.at<cv::Vec3b>(y1, x1);
    auto mix = [&](int k) {
        const float top = a[k] + fx * (b[k] - a[k]), bottom = c[k] + fx * (d[k] - c[k]);
        return static_cast<std::uint8_t>(
            std::clamp(std::lround(top + fy * (bottom - top)), 0L, 255L));
    };
    return {mix(2), mix(1), mix(0)};
}

/// Smooth vertex normals: area-weighted sums of the face normals.
std::vector<Eigen::Vector3d> vertex_normals(const Geometry& g) {
    std::vector<Eigen::Vector3d> n(g.vertices.size(), Eigen::Vector3d::Zero());
    for (const auto& t : g.triangles) {
        const Eigen::Vector3d c =
            (g.vertices[t[1]] - g.vertices[t[0]]).cross(g.vertices[t[2]] - g.vertices[t[0]]);
        for (int j = 0; j < 3; ++j) n[t[j]] += c;
    }
    for (auto& v : n)
        if (v.norm() > 0) v.normalize();
    return n;
}

/// Most points point_spacing() searches among; a larger cloud is subsampled.
constexpr std::size_t kSpacingSample = std::size_t{1} << 18;

/// Typical spacing of the points: median distance to the nearest other point of up to 4000
/// evenly spread points. Exact neighbours from one cell grid (binning a million points is
/// parallel, where a kd-tree over them was a long sequential build for only 4000 queries),
/// without a cell-ordered copy of the points (4000 queries do not repay it); the few queries it
/// does not settle within 8 rings (isolated points) from internal::PointSearch, built then.
/// Beyond kSpacingSample points the spacing is that of a random sample of kSpacingSample of them
/// (fixed seed) times sqrt(sample / points), the spacing of a surface sampled that much more
/// densely: it sets the splats' size only, and binning the 2.2 million points of a 10-view ring's
/// extraction picture cost more than drawing them.
double point_spacing(const std::vector<Eigen::Vector3d>& pts) {
    if (pts.size() < 2) return 0.0;
    if (pts.size() > kSpacingSample) {
        std::vector<char> taken(pts.size(), 0);
        std::vector<Eigen::Vector3d> sample;
        sample.reserve(kSpacingSample);
        std::mt19937_64 rng(7);
        std::uniform_int_distribution<std::size_t> pick(0, pts.size() - 1);
        while (sample.size() < kSpacingSample)
            if (const std::size_t i = pick(rng); !taken[i]) {
                taken[i] = 1;
                sample.push_back(pts[i]);
            }
        return point_spacing(sample) * std::sqrt(double(kSpacingSample) / double(pts.size()));
    }
    const internal::CellNeighbours grid(pts, 2.0, 8, /*ordered=*/false);
    const std::size_t probes = std::min<std::size_t>(4000, pts.size());
    std::vector<double> d(probes, 0.0);
    std::vector<char> unsettled(probes, 0);
    const auto probe = [&](const auto& search, std::size_t i) {
        std::uint32_t idx[2];
        double sq[2];
        const std::size_t found = search.knn(pts[i * pts.size() / probes], 2, idx, sq);
        d[i] = found == 2 ? std::sqrt(sq[1]) : 0.0;
        return found > 0;
    };
    tbb::parallel_for(std::size_t(0), probes,
                      [&](std::size_t i) { unsettled[i] = !grid.ok() || !probe(grid, i); });
    if (std::find(unsettled.begin(), unsettled.end(), 1) != unsettled.end()) {
        const internal::PointSearch search(pts);
        tbb::parallel_for(std::size_t(0), probes, [&](std::size_t i) {
            if (unsettled[i]) probe(search, i);
        });
    }
    return quantile(d, 0.5);
}

cv::Mat render_mesh(const Geometry& g, const Camera& cam, const PictureOptions& options,
                    double smin, double smax) {
    RenderScene scene(g.vertices, g.triangles);
    const std::vector<Eigen::Vector3d> normals = vertex_normals(g);
    const Eigen::Vector3d light = light_direction(cam.world_from_camera);
    const auto& lut = turbo();
    const bool colored = !g.colors.empty(), heat = !g.scalars.empty(), textured = g.is_textured();
    const double range = smax - smin;
    Shader shader = [&](const Eigen::Vector3d& p, int t) -> Rgb {
        const auto& tri = g.triangles[t];
        const Eigen::Vector3d& a = g.vertices[tri[0]];
        const Eigen::Vector3d v0 = g.vertices[tri[1]] - a, v1 = g.vertices[tri[2]] - a, v2 = p - a;
        const double d00 = v0.dot(v0), d01 = v0.dot(v1), d11 = v1.dot(v1), d20 = v2.dot(v0),
                     d21 = v2.dot(v1);
        const double den = d00 * d11 - d01 * d01;
        double w1 = 1.0 / 3, w2 = 1.0 / 3;
        if (std::abs(den) > 0) {
            w1 = std::clamp((d11 * d20 - d01 * d21) / den, 0.0, 1.0);
            w2 = std::clamp((d00 * d21 - d01 * d20) / den, 0.0, 1.0 - w1);
        }
        const double w0 = 1.0 - w1 - w2;
        if (heat) {
            const double s =
                w0 * g.scalars[tri[0]] + w1 * g.scalars[tri[1]] + w2 * g.scalars[tri[2]];
            const double u = std::clamp((s - smin) / range, 0.0, 1.0);
            return lut[static_cast<std::size_t>(std::lround(u * 255.0))];
        }
        Eigen::Vector3d n = w0 * normals[tri[0]] + w1 * normals[tri[1]] + w2 * normals[tri[2]];
        if (!(n.norm() > 1e-9)) n = scene.normals()[t];
        const double l = lambert(n, light);
        if (textured && g.triangle_atlas[t] >= 0) {
            const auto& uv = g.corner_uvs[t];
            const Eigen::Vector2f at = float(w0) * uv[0] + float(w1) * uv[1] + float(w2) * uv[2];
            return scaled(sample_bilinear(g.atlases[g.triangle_atlas[t]], at), 0.7 + 0.3 * l);
        }
        if (colored) {
            const Rgb& c0 = g.colors[tri[0]];
            const Rgb& c1 = g.colors[tri[1]];
            const Rgb& c2 = g.colors[tri[2]];
            auto mix = [&](std::uint8_t x, std::uint8_t y, std::uint8_t z) {
                return static_cast<std::uint8_t>(
                    std::clamp(std::lround(w0 * x + w1 * y + w2 * z), 0L, 255L));
            };
            return scaled({mix(c0.r, c1.r, c2.r), mix(c0.g, c1.g, c2.g), mix(c0.b, c1.b, c2.b)},
                          0.7 + 0.3 * l);
        }
        const std::uint8_t v = grey(0.18 + 0.72 * l);
        return {v, v, v};
    };
    RasterOptions raster;
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const auto& v : g.vertices) centroid += v;
    centroid /= double(g.vertices.size());
    // Near plane far in front of the object only to reject vertices behind the camera.
    raster.near_m = std::max(1e-9, 1e-4 * (cam.world_from_camera.translation() - centroid).norm());
    return render_color(scene, cam.intrinsics, cam.world_from_camera, shader, options.background,
                        raster);
}

cv::Mat render_points(const Geometry& g, const Camera& cam, const PictureOptions& options,
                      double smin, double smax) {
    const PinholeIntrinsics& k = cam.intrinsics;
    const Pose camera_from_world = cam.world_from_camera.inverse();
    const std::size_t n = g.vertices.size();
    std::vector<Eigen::Vector3f> uvz(n);  // u, v, z; z <= 0 = not drawn
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, n, 8192), [&](const tbb::blocked_range<std::size_t>& r) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                const Eigen::Vector3d p = camera_from_world * g.vertices[i];
                if (!(p.z() > 0)) {
                    uvz[i] = Eigen::Vector3f(0, 0, -1);
                    continue;
                }
                uvz[i] = Eigen::Vector3f(float(k.fx * p.x() / p.z() + k.cx),
                                         float(k.fy * p.y() / p.z() + k.cy), float(p.z()));
            }
        });
    // Splat radius in pixels at depth z: radius_px_at_1m / z (0.75 spacings, so neighbours
    // overlap), or fixed.
    const double spacing = options.point_radius_px > 0 ? 0.0 : point_spacing(g.vertices);
    const double radius_at_1m = 0.75 * k.fx * spacing;
    auto radius_of = [&](float z) {
        if (options.point_radius_px > 0) return options.point_radius_px;
        return std::clamp(radius_at_1m / double(z), 0.71, 12.0);
    };
    // Bin points into bands of rows (in index order: deterministic).
    constexpr int kBand = 16;
    const int bands = (k.height + kBand - 1) / kBand;
    std::vector<std::vector<std::uint32_t>> binned(bands);
    for (std::size_t i = 0; i < n; ++i) {
        const Eigen::Vector3f& p = uvz[i];
        if (!(p.z() > 0)) continue;
        const double r = radius_of(p.z());
        const int r0 = std::max(0, static_cast<int>(std::ceil(p.y() - r)));
        const int r1 = std::min(k.height - 1, static_cast<int>(std::floor(p.y() + r)));
        if (r1 < r0 || p.x() + r < 0 || p.x() - r > k.width - 1) continue;
        for (int b = r0 / kBand; b <= r1 / kBand; ++b)
            binned[b].push_back(static_cast<std::uint32_t>(i));
    }
    const std::size_t pixels = static_cast<std::size_t>(k.width) * k.height;
    std::vector<float> zbuf(pixels, std::numeric_limits<float>::infinity());
    std::vector<std::int64_t> owner(pixels, -1);
    tbb::parallel_for(0, bands, [&](int b) {
        const int first = b * kBand, last = std::min(k.height - 1, first + kBand - 1);
        for (const std::uint32_t i : binned[b]) {
            const Eigen::Vector3f& p = uvz[i];
            const double r = radius_of(p.z());
            const int r0 = std::max(first, static_cast<int>(std::ceil(p.y() - r)));
            const int r1 = std::min(last, static_cast<int>(std::floor(p.y() + r)));
            const int c0 = std::max(0, static_cast<int>(std::ceil(p.x() - r)));
            const int c1 = std::min(k.width - 1, static_cast<int>(std::floor(p.x() + r)));
            for (int row = r0; row <= r1; ++row)
                for (int col = c0; col <= c1; ++col) {
                    const double du = col - p.x(), dv = row - p.y();
                    if (du * du + dv * dv > r * r) continue;
                    const std::size_t px = static_cast<std::size_t>(row) * k.width + col;
                    if (p.z() < zbuf[px]) {
                        zbuf[px] = p.z();
                        owner[px] = i;
                    }
                }
        }
    });
    // Depth cue range for clouds without colour or normals.
    float zmin = std::numeric_limits<float>::infinity(), zmax = 0;
    for (std::size_t px = 0; px < pixels; ++px)
        if (owner[px] >= 0) {
            zmin = std::min(zmin, zbuf[px]);
            zmax = std::max(zmax, zbuf[px]);
        }
    const Eigen::Vector3d light = light_direction(cam.world_from_camera);
    const auto& lut = turbo();
    cv::Mat out(k.height, k.width, CV_8UC3);
    tbb::parallel_for(0, k.height, [&](int row) {
        auto* c = out.ptr<cv::Vec3b>(row);
        for (int col = 0; col < k.width; ++col) {
            const std::int64_t i = owner[static_cast<std::size_t>(row) * k.width + col];
            Rgb rgb = options.background;
            if (i >= 0) {
                if (!g.scalars.empty()) {
                    const double u = std::clamp((g.scalars[i] - smin) / (smax - smin), 0.0, 1.0);
                    rgb = lut[static_cast<std::size_t>(std::lround(u * 255.0))];
                } else if (!g.colors.empty()) {
                    rgb = g.colors[i];
                } else if (!g.normals.empty()) {
                    const std::uint8_t v = grey(0.18 + 0.72 * lambert(g.normals[i], light));
                    rgb = {v, v, v};
                } else {
                    const float z = zbuf[static_cast<std::size_t>(row) * k.width + col];
                    const double t = zmax > zmin ? (zmax - z) / (zmax - zmin) : 0.5;
                    const std::uint8_t v = grey(0.3 + 0.5 * t);
                    rgb = {v, v, v};
                }
            }
            c[col] = cv::Vec3b(rgb.b, rgb.g, rgb.r);
        }
    });
    return out;
}

}  // namespace

void Geometry::check(const std::string& what) const {
    RGBD_CHECK(!vertices.empty(), what + ": nothing to draw (no points)");
    for (const auto& v : vertices) RGBD_CHECK(v.allFinite(), what + ": non-finite coordinates");
    const long long n = static_cast<long long>(vertices.size());
    for (const auto& t : triangles)
        for (int j = 0; j < 3; ++j)
            RGBD_CHECK(t[j] >= 0 && t[j] < n, what + ": triangle vertex index out of range");
    RGBD_CHECK(colors.empty() || colors.size() == vertices.size(),
               what + ": colour count differs from the vertex count");
    RGBD_CHECK(normals.empty() || normals.size() == vertices.size(),
               what + ": normal count differs from the vertex count");
    RGBD_CHECK(scalars.empty() || scalars.size() == vertices.size(),
               what + ": value count differs from the vertex count");
    for (double s : scalars) RGBD_CHECK(std::isfinite(s), what + ": non-finite value");
    if (atlases.empty()) return;
    RGBD_CHECK(triangle_atlas.size() == triangles.size() && corner_uvs.size() == triangles.size(),
               what + ": texture coordinates not one set per triangle");
    for (const auto& a : atlases)
        RGBD_CHECK(a.type() == CV_8UC3 && !a.empty(), what + ": a texture atlas is not 8-bit RGB");
    for (int a : triangle_atlas)
        RGBD_CHECK(a >= -1 && a < static_cast<int>(atlases.size()),
                   what + ": texture atlas index out of range");
}

Geometry from_mesh(const Mesh& mesh) {
    Geometry g;
    std::vector<int> index(mesh.num_vertices(), -1);
    const auto colors = vertex_colors(mesh);
    for (const auto v : mesh.vertices()) {
        index[v.idx()] = static_cast<int>(g.vertices.size());
        g.vertices.push_back(to_eigen(mesh.point(v)));
        if (colors) {
            const MeshColor& c = (*colors)[v];
            g.colors.push_back({c.red(), c.green(), c.blue()});
        }
    }
    for (const auto f : mesh.faces()) {
        std::vector<int> ids;
        for (const auto v : CGAL::vertices_around_face(mesh.halfedge(f), mesh))
            ids.push_back(index[v.idx()]);
        for (std::size_t j = 1; j + 1 < ids.size(); ++j)
            g.triangles.push_back({ids[0], ids[j], ids[j + 1]});
    }
    return g;
}

Geometry from_textured_mesh(const TexturedMesh& mesh) {
    Geometry g;
    g.vertices = mesh.vertices;
    g.triangles = mesh.faces;
    g.colors = mesh.vertex_colors;
    if (!mesh.has_texture()) return g;
    g.atlases = mesh.atlases;
    g.triangle_atlas.resize(mesh.faces.size(), -1);
    g.corner_uvs.resize(mesh.faces.size());
    const int n_uvs = static_cast<int>(mesh.uvs.size());
    for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
        const auto& ids = mesh.face_uvs[f];
        if (ids[0] < 0 || ids[0] >= n_uvs || ids[1] < 0 || ids[1] >= n_uvs || ids[2] < 0 ||
            ids[2] >= n_uvs)
            continue;  // no texture on this face: its vertex colours
        g.triangle_atlas[f] = f < mesh.face_atlas.size() ? mesh.face_atlas[f] : 0;
        for (int j = 0; j < 3; ++j) g.corner_uvs[f][j] = mesh.uvs[ids[j]];
    }
    return g;
}

Geometry from_views(const std::vector<PointCloud>& views) {
    Geometry g;
    bool colors = !views.empty(), normals = !views.empty();
    // Each view's points go to [offset[v], offset[v + 1]) of the arrays, filled in parallel.
    std::vector<std::size_t> offset(views.size() + 1, 0);
    std::vector<Pose> world_from_view(views.size(), Pose::Identity());
    for (std::size_t v = 0; v < views.size(); ++v) {
        const PointCloud& view = views[v];
        colors = colors && view.has_colors();
        normals = normals && view.points.has_normal_map();
        offset[v + 1] = offset[v] + view.points.size();
        // A view in its sensor frame is moved by its pose; without one (a plain point file)
        // it is drawn as it is, and a sensor view (with intrinsics) counts as a sensor at the
        // origin for the orientation.
        if (view.view.frame == ViewFrame::kSensor && view.view.world_from_sensor)
            world_from_view[v] = *view.view.world_from_sensor;
        if (view.view.world_from_sensor)
            g.sensors.push_back(*view.view.world_from_sensor);
        else if (view.view.frame == ViewFrame::kSensor && view.view.intrinsics)
            g.sensors.push_back(Pose::Identity());
    }
    g.vertices.resize(offset.back());
    if (colors) g.colors.resize(offset.back());
    if (normals) g.normals.resize(offset.back());
    tbb::parallel_for(std::size_t(0), views.size(), [&](std::size_t v) {
        const PointCloud& view = views[v];
        const Pose& pose = world_from_view[v];
        std::optional<PointCloud::ColorMaps> cm;
        if (colors) cm = view.colors();
        std::size_t a = offset[v];
        for (auto i : view.points) {
            g.vertices[a] = pose * to_eigen(view.points.point(i));
            if (cm) g.colors[a] = cm->get(i);
            if (normals) g.normals[a] = pose.linear() * to_eigen(view.points.normal(i));
            ++a;
        }
    });
    return g;
}

namespace {

constexpr EnumName<ViewDirection> kViewNames[] = {
    {ViewDirection::kAuto, "auto"},   {ViewDirection::kFront, "front"},
    {ViewDirection::kBack, "back"},   {ViewDirection::kLeft, "left"},
    {ViewDirection::kRight, "right"}, {ViewDirection::kTop, "top"}};

/// Where each direction looks from: azimuth from the front towards the right and elevation
/// above the horizon, degrees (kAuto: the three-quarter view).
struct ViewAngles {
    ViewDirection direction;
    double azimuth_deg, elevation_deg;
};
constexpr ViewAngles kViewAngles[] = {
    {ViewDirection::kAuto, 35, 20}, {ViewDirection::kFront, 0, 0},  {ViewDirection::kBack, 180, 0},
    {ViewDirection::kLeft, -90, 0}, {ViewDirection::kRight, 90, 0}, {ViewDirection::kTop, 0, 90}};

}  // namespace

ViewDirection parse_view_direction(const std::string& name) {
    if (const auto direction = value_of(kViewNames, name)) return *direction;
    throw InputError("unknown view '" + name + "' (auto, front, back, left, right or top)");
}

Orientation guess_orientation(const std::vector<Pose>& sensors, const Eigen::Vector3d& centre,
                              const std::optional<Eigen::Vector3d>& up) {
    Orientation o;
    if (up) {
        RGBD_CHECK(up->allFinite() && up->norm() > 0, "the up direction must be a non-zero vector");
        o.up = up->normalized();
    } else if (const auto seen = sensors_up(sensors)) {
        o.up = *seen;
    }
    auto horizontal = [&](const Eigen::Vector3d& d) -> Eigen::Vector3d {
        return d - d.dot(o.up) * o.up;
    };
    Eigen::Vector3d front = Eigen::Vector3d::Zero();
    if (!sensors.empty()) {
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        double spread = 0;
        for (const auto& s : sensors) mean += horizontal(s.translation() - centre);
        mean /= double(sensors.size());
        for (const auto& s : sensors) spread += horizontal(s.translation() - centre).norm();
        spread /= double(sensors.size());
        // A ring (mean near the centre): the first sensor's side is the front.
        front =
            mean.norm() > 0.3 * spread ? mean : horizontal(sensors.front().translation() - centre);
    }
    if (!(front.norm() > 1e-9)) {
        const std::array<Eigen::Vector3d, 4> axes = {
            Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 0, -1),
            Eigen::Vector3d(-1, 0, 0)};
        for (const Eigen::Vector3d& axis : axes) {
            front = horizontal(axis);
            if (front.norm() > 0.5) break;
        }
    }
    o.front = front.normalized();
    return o;
}

void CameraOptions::check() const {
    check_range("picture width", width, Range::closed(16, 16384), "pixels");
    check_range("picture height", height, Range::closed(16, 16384), "pixels");
    RGBD_CHECK(!azimuth_deg || std::isfinite(*azimuth_deg), "azimuth must be finite");
    RGBD_CHECK(!elevation_deg || (std::isfinite(*elevation_deg) && std::abs(*elevation_deg) <= 90),
               "elevation must be within -90..90 degrees");
    check_range("margin", margin, Range::closed_open(0, 0.4));
    RGBD_CHECK(std::isfinite(distance_factor) && distance_factor > 1.2,
               "distance factor must be > 1.2");
}

Camera fit_camera(const std::vector<Eigen::Vector3d>& points, const Orientation& o,
                  const CameraOptions& options) {
    options.check();
    std::vector<Eigen::Vector3d> finite;
    finite.reserve(points.size());
    for (const auto& p : points)
        if (p.allFinite()) finite.push_back(p);
    RGBD_CHECK(!finite.empty(), "nothing to draw (no finite point)");
    // Robust box from a stride sample of at most 100k points.
    const std::size_t stride = std::max<std::size_t>(1, finite.size() / 100000);
    Eigen::Vector3d lo, hi;
    for (int axis = 0; axis < 3; ++axis) {
        std::vector<double> v;
        for (std::size_t i = 0; i < finite.size(); i += stride) v.push_back(finite[i][axis]);
        lo[axis] = quantile(v, 0.002);
        hi[axis] = quantile(v, 0.998);
    }
    const Eigen::Vector3d centre = 0.5 * (lo + hi);
    const double radius = std::max(0.5 * (hi - lo).norm(), 1e-6);

    double az = 35, el = 20;
    for (const ViewAngles& v : kViewAngles)
        if (v.direction == options.view) az = v.azimuth_deg, el = v.elevation_deg;
    if (options.azimuth_deg) az = *options.azimuth_deg;
    if (options.elevation_deg) el = *options.elevation_deg;
    const double a = az * kPi / 180, e = el * kPi / 180;
    const Eigen::Vector3d right = o.up.cross(o.front).normalized();
    const Eigen::Vector3d towards_front = std::cos(a) * o.front + std::sin(a) * right;
    const Eigen::Vector3d dir = (std::cos(e) * towards_front + std::sin(e) * o.up).normalized();
    const Eigen::Vector3d z = -dir;
    Eigen::Vector3d image_up = o.up - o.up.dot(z) * z;
    if (image_up.norm() < 1e-6) image_up = -towards_front;  // straight from above or below
    const Eigen::Vector3d y = -image_up.normalized();
    const Eigen::Vector3d x = y.cross(z);
    Camera cam;
    cam.world_from_camera.linear().col(0) = x;
    cam.world_from_camera.linear().col(1) = y;
    cam.world_from_camera.linear().col(2) = z;
    cam.world_from_camera.translation() = centre + dir * options.distance_factor * radius;
    const Pose camera_from_world = cam.world_from_camera.inverse();

    double xmin = 1e300, xmax = -1e300, ymin = 1e300, ymax = -1e300;
    for (const auto& p : finite) {
        if (((p - lo).array() < 0).any() || ((p - hi).array() > 0).any()) continue;
        const Eigen::Vector3d q = camera_from_world * p;
        xmin = std::min(xmin, q.x() / q.z());
        xmax = std::max(xmax, q.x() / q.z());
        ymin = std::min(ymin, q.y() / q.z());
        ymax = std::max(ymax, q.y() / q.z());
    }
    const double usable_w = options.width * (1 - 2 * options.margin);
    const double usable_h = options.height * (1 - 2 * options.margin);
    const double f =
        std::min(usable_w / std::max(xmax - xmin, 1e-9), usable_h / std::max(ymax - ymin, 1e-9));
    PinholeIntrinsics& k = cam.intrinsics;
    k.width = options.width;
    k.height = options.height;
    k.fx = k.fy = f;
    k.cx = 0.5 * (options.width - 1) - f * 0.5 * (xmin + xmax);
    k.cy = 0.5 * (options.height - 1) - f * 0.5 * (ymin + ymax);
    return cam;
}

void PictureOptions::check() const {
    check_range("point radius", point_radius_px, Range::closed(0, 100), "pixels");
    RGBD_CHECK(!scalar_min || std::isfinite(*scalar_min),
               "value range minimum must be finite, got " + format_number(*scalar_min));
    RGBD_CHECK(!scalar_max || std::isfinite(*scalar_max),
               "value range maximum must be finite, got " + format_number(*scalar_max));
    RGBD_CHECK(!(scalar_min && scalar_max) || *scalar_min < *scalar_max,
               "value range minimum must be below its maximum");
    RGBD_CHECK(std::isfinite(scalar_display_scale) && scalar_display_scale != 0,
               "display scale must be finite and non-zero");
}

Rgb heat_color(double t) {
    if (!(t > 0)) t = 0;
    return turbo()[static_cast<std::size_t>(std::lround(std::min(t, 1.0) * 255.0))];
}

Picture render_picture(const Geometry& g, const Camera& camera, const PictureOptions& options) {
    g.check("picture");
    options.check();
    camera.intrinsics.check();
    Picture pic;
    pic.camera = camera;
    pic.model_area = cv::Rect(0, 0, camera.intrinsics.width, camera.intrinsics.height);
    if (!g.scalars.empty()) {
        const double lo = *std::min_element(g.scalars.begin(), g.scalars.end());
        pic.scalar_min = options.scalar_min ? *options.scalar_min : std::min(lo, 0.0);
        pic.scalar_max = options.scalar_max ? *options.scalar_max : quantile(g.scalars, 0.98);
        if (!(pic.scalar_max > pic.scalar_min))
            pic.scalar_max = pic.scalar_min + std::max(1e-12, std::abs(pic.scalar_min) * 1e-6);
    }
    const cv::Mat model = g.is_mesh()
                              ? render_mesh(g, camera, options, pic.scalar_min, pic.scalar_max)
                              : render_points(g, camera, options, pic.scalar_min, pic.scalar_max);
    const cv::Vec3b bg(options.background.b, options.background.g, options.background.r);
    for (int r = 0; r < model.rows; ++r)
        for (int c = 0; c < model.cols; ++c) pic.covered_pixels += model.at<cv::Vec3b>(r, c) != bg;
    if (g.scalars.empty())
        pic.image = model;
    else
        add_color_bar(pic, model, options);
    return pic;
}

}  // namespace rgbd::render
