#include "algorithms/render/rasterizer.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "toolkit/error.hpp"

namespace rgbd::render {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// A triangle projected into one camera.
struct Projected {
    Eigen::Vector2d uv[3];
    double inv_z[3];
    int row_min = 0, row_max = -1, col_min = 0, col_max = -1;  // inclusive pixel bounds
    double area2 = 0;                                          // twice the signed screen area
};

/// Z-buffer result: depth and triangle per pixel.
struct ZBuffer {
    int width = 0, height = 0;
    std::vector<double> depth;
    std::vector<int> triangle;
};

double edge(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double px, double py) {
    return (b.x() - a.x()) * (py - a.y()) - (b.y() - a.y()) * (px - a.x());
}

ZBuffer rasterize(const RenderScene& scene, const PinholeIntrinsics& k,
                  const Pose& world_from_camera, const RasterOptions& options) {
    options.check();
    k.check();
    RGBD_CHECK(k.distortion.is_none(),
               "software rendering supports pinhole cameras without distortion only");
    const Pose camera_from_world = world_from_camera.inverse();
    const auto& verts = scene.vertices();
    const auto& tris = scene.triangles();

    // Vertices in the camera frame.
    std::vector<Eigen::Vector3d> pc(verts.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, verts.size(), 4096),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t i = r.begin(); i != r.end(); ++i)
                              pc[i] = camera_from_world * verts[i];
                      });

    // Project triangles and compute their pixel bounds.
    std::vector<Projected> proj(tris.size());
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, tris.size(), 2048),
        [&](const tbb::blocked_range<std::size_t>& r) {
            for (std::size_t t = r.begin(); t != r.end(); ++t) {
                Projected& p = proj[t];
                bool ok = true;
                for (int j = 0; j < 3; ++j) {
                    const Eigen::Vector3d& v = pc[tris[t][j]];
                    if (!(v.z() >= options.near_m)) {
                        ok = false;
                        break;
                    }
                    p.uv[j] = {k.fx * v.x() / v.z() + k.cx, k.fy * v.y() / v.z() + k.cy};
                    p.inv_z[j] = 1.0 / v.z();
                }
                if (!ok) continue;
                p.area2 = edge(p.uv[0], p.uv[1], p.uv[2].x(), p.uv[2].y());
                if (!(std::abs(p.area2) > 0)) continue;
                const double umin = std::min({p.uv[0].x(), p.uv[1].x(), p.uv[2].x()});
                const double umax = std::max({p.uv[0].x(), p.uv[1].x(), p.uv[2].x()});
                const double vmin = std::min({p.uv[0].y(), p.uv[1].y(), p.uv[2].y()});
                const double vmax = std::max({p.uv[0].y(), p.uv[1].y(), p.uv[2].y()});
                if (umax < 0 || vmax < 0 || umin > k.width - 1 || vmin > k.height - 1) continue;
                p.col_min = std::max(0, static_cast<int>(std::ceil(umin)));
                p.col_max = std::min(k.width - 1, static_cast<int>(std::floor(umax)));
                p.row_min = std::max(0, static_cast<int>(std::ceil(vmin)));
                p.row_max = std::min(k.height - 1, static_cast<int>(std::floor(vmax)));
            }
        });

    // Bin triangles into bands of rows, in triangle order (deterministic).
    const int band_rows = options.band_rows;
    const int bands = (k.height + band_rows - 1) / band_rows;
    std::vector<std::vector<int>> binned(bands);
    for (std::size_t t = 0; t < tris.size(); ++t) {
        const Projected& p = proj[t];
        if (p.row_max < p.row_min || p.col_max < p.col_min) continue;
        for (int b = p.row_min / band_rows; b <= p.row_max / band_rows; ++b)
            binned[b].push_back(static_cast<int>(t));
    }

    ZBuffer zb;
    zb.width = k.width;
    zb.height = k.height;
    zb.depth.assign(static_cast<std::size_t>(k.width) * k.height,
                    std::numeric_limits<double>::infinity());
    zb.triangle.assign(zb.depth.size(), -1);
    tbb::parallel_for(0, bands, [&](int b) {
        const int band_first = b * band_rows;
        const int band_last = std::min(k.height - 1, band_first + band_rows - 1);
        for (const int t : binned[b]) {
            const Projected& p = proj[t];
            const double inv_area = 1.0 / p.area2;
            const int r0 = std::max(p.row_min, band_first);
            const int r1 = std::min(p.row_max, band_last);
            for (int row = r0; row <= r1; ++row) {
                for (int col = p.col_min; col <= p.col_max; ++col) {
                    // Barycentrics in screen space; pixels on an edge belong to both triangles
                    // and the z-test (then the lower id) decides.
                    const double w0 = edge(p.uv[1], p.uv[2], col, row) * inv_area;
                    const double w1 = edge(p.uv[2], p.uv[0], col, row) * inv_area;
                    const double w2 = edge(p.uv[0], p.uv[1], col, row) * inv_area;
                    if (w0 < 0 || w1 < 0 || w2 < 0) continue;
                    const double inv_z = w0 * p.inv_z[0] + w1 * p.inv_z[1] + w2 * p.inv_z[2];
                    if (!(inv_z > 0)) continue;
                    const double z = 1.0 / inv_z;
                    const std::size_t i = static_cast<std::size_t>(row) * k.width + col;
                    if (z < zb.depth[i]) {
                        zb.depth[i] = z;
                        zb.triangle[i] = t;
                    }
                }
            }
        }
    });
    return zb;
}

/// Exact depth of the pixel ray on the plane of triangle t (camera frame), which removes the
/// rounding of the screen-space interpolation.
double ray_plane_depth(const Eigen::Vector3d& n_cam, const Eigen::Vector3d& a_cam, double x,
                       double y) {
    const Eigen::Vector3d ray(x, y, 1.0);
    const double denom = n_cam.dot(ray);
    if (!(std::abs(denom) > 1e-12)) return kNaN;
    return n_cam.dot(a_cam) / denom;
}

}  // namespace

void RasterOptions::check() const {
    RGBD_CHECK(std::isfinite(near_m) && near_m > 0, "near plane must be > 0");
    RGBD_CHECK(band_rows >= 1 && band_rows <= 100000, "band_rows must be >= 1");
}

RenderScene::RenderScene(const Mesh& mesh) {
    RGBD_CHECK(mesh.number_of_faces() > 0, "cannot render a mesh without faces");
    std::vector<int> index(mesh.num_vertices(), -1);
    for (const auto v : mesh.vertices()) {
        const Eigen::Vector3d p = to_eigen(mesh.point(v));
        RGBD_CHECK(p.allFinite(), "mesh has non-finite vertex coordinates");
        index[v.idx()] = static_cast<int>(vertices_.size());
        vertices_.push_back(p);
    }
    for (const auto f : mesh.faces()) {
        std::vector<int> ids;
        for (const auto v : CGAL::vertices_around_face(mesh.halfedge(f), mesh))
            ids.push_back(index[v.idx()]);
        for (std::size_t j = 1; j + 1 < ids.size(); ++j)
            triangles_.push_back({ids[0], ids[j], ids[j + 1]});
    }
    RGBD_CHECK(!triangles_.empty(), "cannot render a mesh without triangles");
    compute_normals();
}

RenderScene::RenderScene(std::vector<Eigen::Vector3d> vertices,
                         std::vector<std::array<int, 3>> triangles)
    : vertices_(std::move(vertices)), triangles_(std::move(triangles)) {
    RGBD_CHECK(!triangles_.empty(), "cannot render a mesh without triangles");
    for (const auto& p : vertices_)
        RGBD_CHECK(p.allFinite(), "mesh has non-finite vertex coordinates");
    const long long n = static_cast<long long>(vertices_.size());
    for (const auto& t : triangles_)
        for (int j = 0; j < 3; ++j)
            RGBD_CHECK(t[j] >= 0 && t[j] < n, "triangle vertex index out of range");
    compute_normals();
}

void RenderScene::compute_normals() {
    normals_.resize(triangles_.size());
    for (std::size_t t = 0; t < triangles_.size(); ++t) {
        const auto& tr = triangles_[t];
        const Eigen::Vector3d n =
            (vertices_[tr[1]] - vertices_[tr[0]]).cross(vertices_[tr[2]] - vertices_[tr[0]]);
        const double len = n.norm();
        normals_[t] = len > 0 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
    }
}

cv::Mat DepthRender::depth_float() const {
    cv::Mat out;
    depth.convertTo(out, CV_32F);
    return out;
}

DepthRender render_depth(const RenderScene& scene, const PinholeIntrinsics& k,
                         const Pose& world_from_camera, const RasterOptions& options) {
    const ZBuffer zb = rasterize(scene, k, world_from_camera, options);
    const Eigen::Matrix3d camera_from_world_r = world_from_camera.linear().transpose();
    const Pose camera_from_world = world_from_camera.inverse();
    DepthRender out;
    out.depth.create(k.height, k.width, CV_64FC1);
    out.normal.create(k.height, k.width, CV_32FC3);
    out.triangle.create(k.height, k.width, CV_32SC1);
    tbb::parallel_for(0, k.height, [&](int row) {
        auto* d = out.depth.ptr<double>(row);
        auto* n = out.normal.ptr<cv::Vec3f>(row);
        auto* tri = out.triangle.ptr<int>(row);
        for (int col = 0; col < k.width; ++col) {
            const std::size_t i = static_cast<std::size_t>(row) * k.width + col;
            const int t = zb.triangle[i];
            tri[col] = t;
            if (t < 0) {
                d[col] = kNaN;
                n[col] = cv::Vec3f(kNaN, kNaN, kNaN);
                continue;
            }
            Eigen::Vector3d nc = camera_from_world_r * scene.normals()[t];
            const Eigen::Vector3d a = camera_from_world * scene.vertices()[scene.triangles()[t][0]];
            const double x = (col - k.cx) / k.fx;
            const double y = (row - k.cy) / k.fy;
            double z = ray_plane_depth(nc, a, x, y);
            // Refine only when the exact plane depth agrees with the interpolated one (it
            // cannot disagree except for near-degenerate, grazing triangles).
            if (!(std::abs(z - zb.depth[i]) < 1e-6 * zb.depth[i])) z = zb.depth[i];
            d[col] = z;
            if (nc.dot(Eigen::Vector3d(x, y, 1.0)) > 0) nc = -nc;  // face the camera
            n[col] = cv::Vec3f(static_cast<float>(nc.x()), static_cast<float>(nc.y()),
                               static_cast<float>(nc.z()));
        }
    });
    return out;
}

cv::Mat render_color(const RenderScene& scene, const PinholeIntrinsics& k,
                     const Pose& world_from_camera, const Shader& shader, Rgb background,
                     const RasterOptions& options) {
    RGBD_CHECK(static_cast<bool>(shader), "render_color needs a shader");
    const ZBuffer zb = rasterize(scene, k, world_from_camera, options);
    cv::Mat out(k.height, k.width, CV_8UC3);
    tbb::parallel_for(0, k.height, [&](int row) {
        auto* c = out.ptr<cv::Vec3b>(row);
        for (int col = 0; col < k.width; ++col) {
            const std::size_t i = static_cast<std::size_t>(row) * k.width + col;
            const int t = zb.triangle[i];
            Rgb rgb = background;
            if (t >= 0) {
                const double z = zb.depth[i];
                const Eigen::Vector3d p_cam((col - k.cx) / k.fx * z, (row - k.cy) / k.fy * z, z);
                rgb = shader(world_from_camera * p_cam, t);
            }
            c[col] = cv::Vec3b(rgb.b, rgb.g, rgb.r);
        }
    });
    return out;
}

}  // namespace rgbd::render
