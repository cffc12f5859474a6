#include "algorithms/texture/view_selection.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <map>
#include <opencv2/imgproc.hpp>
#include <utility>

#include "toolkit/error.hpp"

namespace rgbd::texture {
namespace {

/// Gradient magnitude of the image's grey levels, smoothed over a few pixels, and its mean.
std::pair<cv::Mat, double> sharpness_map(const cv::Mat& bgr) {
    cv::Mat grey, gx, gy, mag;
    cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
    cv::Sobel(grey, gx, CV_32F, 1, 0, 3);
    cv::Sobel(grey, gy, CV_32F, 0, 1, 3);
    cv::magnitude(gx, gy, mag);
    cv::GaussianBlur(mag, mag, cv::Size(0, 0), 2.0);
    return {mag, cv::mean(mag)[0]};
}

/// The quality row of one view.
void view_quality(const render::RenderScene& scene, const TextureView& view,
                  const SelectionOptions& options, float* row) {
    const PinholeIntrinsics& k = view.intrinsics;
    const render::DepthRender depth = render::render_depth(scene, k, view.world_from_camera);
    const Pose camera_from_world = view.world_from_camera.inverse();
    const Eigen::Vector3d centre = view.world_from_camera.translation();
    cv::Mat sharp;
    double sharp_mean = 0;
    if (options.sharpness) std::tie(sharp, sharp_mean) = sharpness_map(view.image);
    const auto& verts = scene.vertices();
    const auto& tris = scene.triangles();
    const double lo = options.border_px;
    const double hi_u = k.width - 1 - options.border_px, hi_v = k.height - 1 - options.border_px;
    // True when the camera-frame point p passes the depth test against the rendered mesh.
    auto visible = [&](const Eigen::Vector3d& p) {
        const Eigen::Vector2d uv = k.project(p);
        const int c = static_cast<int>(std::lround(uv.x())),
                  r = static_cast<int>(std::lround(uv.y()));
        if (c < 0 || r < 0 || c >= k.width || r >= k.height) return false;
        const double d = depth.depth.at<double>(r, c);
        if (!std::isfinite(d)) return false;
        return p.z() <= d + options.depth_tolerance_m + options.depth_tolerance_rel * p.z();
    };
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, tris.size(), 4096),
        [&](const tbb::blocked_range<std::size_t>& range) {
            for (std::size_t f = range.begin(); f != range.end(); ++f) {
                row[f] = 0;
                const Eigen::Vector3d& n = scene.normals()[f];
                if (n.isZero()) continue;
                const auto& t = tris[f];
                const Eigen::Vector3d cw = (verts[t[0]] + verts[t[1]] + verts[t[2]]) / 3.0;
                const double cos = n.dot((centre - cw).normalized());
                if (!(cos >= options.min_cos)) continue;
                Eigen::Vector3d pc[3];
                Eigen::Vector2d uv[3];
                bool inside = true;
                for (int j = 0; j < 3 && inside; ++j) {
                    pc[j] = camera_from_world * verts[t[j]];
                    if (!(pc[j].z() > 0.05)) {
                        inside = false;
                        break;
                    }
                    uv[j] = k.project(pc[j]);
                    inside = uv[j].x() >= lo && uv[j].y() >= lo && uv[j].x() <= hi_u &&
                             uv[j].y() <= hi_v;
                }
                if (!inside) continue;
                const Eigen::Vector3d cc = camera_from_world * cw;
                // The centre and three points between it and the corners must all be visible: a
                // partly hidden face would take the colour of what hides it.
                bool seen = visible(cc);
                for (int j = 0; j < 3 && seen; ++j) seen = visible((2.0 * pc[j] + cc) / 3.0);
                if (!seen) continue;
                const Eigen::Vector2d e1 = uv[1] - uv[0], e2 = uv[2] - uv[0];
                const double area_px = 0.5 * std::abs(e1.x() * e2.y() - e1.y() * e2.x());
                double q = std::max(area_px, 1e-3) * cos;
                if (options.sharpness && sharp_mean > 0) {
                    const Eigen::Vector2d m = (uv[0] + uv[1] + uv[2]) / 3.0;
                    const float g = sharp.at<float>(static_cast<int>(std::lround(m.y())),
                                                    static_cast<int>(std::lround(m.x())));
                    q *= std::clamp(g / sharp_mean, 0.5, 2.0);
                }
                row[f] = static_cast<float>(q);
            }
        });
}

}  // namespace

void SelectionOptions::check() const {
    RGBD_CHECK(std::isfinite(min_cos) && min_cos >= 0 && min_cos < 1,
               "texture: min_cos must be in [0, 1)");
    RGBD_CHECK(std::isfinite(depth_tolerance_m) && depth_tolerance_m >= 0 && depth_tolerance_m <= 1,
               "texture: depth tolerance must be in [0, 1] m");
    RGBD_CHECK(
        std::isfinite(depth_tolerance_rel) && depth_tolerance_rel >= 0 && depth_tolerance_rel <= 1,
        "texture: relative depth tolerance must be in [0, 1]");
    RGBD_CHECK(border_px >= 0 && border_px <= 1000, "texture: border must be in [0, 1000] px");
    RGBD_CHECK(std::isfinite(smoothness) && smoothness >= 0 && smoothness <= 100,
               "texture: smoothness must be in [0, 100]");
    RGBD_CHECK(sweeps >= 0 && sweeps <= 1000, "texture: sweeps must be in [0, 1000]");
}

FaceQuality face_quality(const render::RenderScene& scene, const std::vector<TextureView>& views,
                         const SelectionOptions& options, const Progress& progress) {
    options.check();
    for (const auto& v : views) {
        v.intrinsics.check();
        RGBD_CHECK(v.intrinsics.distortion.is_none(),
                   v.name + ": texturing needs undistorted colour images");
        RGBD_CHECK(!v.image.empty() && v.image.type() == CV_8UC3 &&
                       v.image.cols == v.intrinsics.width && v.image.rows == v.intrinsics.height,
                   v.name + ": colour image missing or not of the colour camera's size (" +
                       std::to_string(v.intrinsics.width) + " x " +
                       std::to_string(v.intrinsics.height) + ")");
    }
    FaceQuality out;
    out.views = static_cast<int>(views.size());
    out.faces = static_cast<int>(scene.triangles().size());
    out.quality.assign(static_cast<std::size_t>(out.views) * out.faces, 0.0f);
    std::atomic<int> done{0};
    tbb::parallel_for(0, out.views, [&](int v) {
        view_quality(scene, views[v], options,
                     out.quality.data() + static_cast<std::size_t>(v) * out.faces);
        report_progress(progress, (++done) / static_cast<double>(out.views));
    });
    return out;
}

std::vector<std::array<int, 3>> face_adjacency(const std::vector<std::array<int, 3>>& triangles) {
    std::vector<std::array<int, 3>> adjacency(triangles.size(), {-1, -1, -1});
    // Edge (low, high) -> first face and its edge slot; a third face marks it non-manifold.
    std::map<std::pair<int, int>, std::array<int, 3>> edges;  // face, slot, count
    for (std::size_t f = 0; f < triangles.size(); ++f) {
        for (int j = 0; j < 3; ++j) {
            const int a = triangles[f][j], b = triangles[f][(j + 1) % 3];
            auto [it, fresh] = edges.try_emplace({std::min(a, b), std::max(a, b)},
                                                 std::array<int, 3>{static_cast<int>(f), j, 1});
            if (fresh) continue;
            auto& e = it->second;
            ++e[2];
            if (e[2] == 2) {
                adjacency[e[0]][e[1]] = static_cast<int>(f);
                adjacency[f][j] = e[0];
            } else if (e[2] == 3) {
                // Non-manifold: unlink the pair linked before.
                const int g = adjacency[e[0]][e[1]];
                adjacency[e[0]][e[1]] = -1;
                for (auto& s : adjacency[g])
                    if (s == e[0]) s = -1;
            }
        }
    }
    return adjacency;
}

Selection select_views(const FaceQuality& quality, const std::vector<std::array<int, 3>>& adjacency,
                       const SelectionOptions& options) {
    options.check();
    RGBD_CHECK(adjacency.size() == static_cast<std::size_t>(quality.faces),
               "texture: adjacency and quality disagree on the number of faces");
    const int nf = quality.faces, nv = quality.views;
    Selection out;
    out.label.assign(nf, -1);
    std::vector<float> best(nf, 0.0f);
    for (int f = 0; f < nf; ++f)
        for (int v = 0; v < nv; ++v)
            if (quality.at(v, f) > best[f]) {
                best[f] = quality.at(v, f);
                out.label[f] = v;
            }
    const std::vector<int> initial = out.label;
    for (int sweep = 0; sweep < options.sweeps; ++sweep) {
        std::size_t changed = 0;
        for (int f = 0; f < nf; ++f) {
            if (out.label[f] < 0) continue;
            int arg = out.label[f];
            double min_cost = std::numeric_limits<double>::infinity();
            for (int v = 0; v < nv; ++v) {
                const float q = quality.at(v, f);
                if (!(q > 0)) continue;
                double cost = 1.0 - q / best[f];
                for (const int g : adjacency[f])
                    if (g >= 0 && out.label[g] >= 0 && out.label[g] != v)
                        cost += options.smoothness;
                if (cost < min_cost - 1e-12) {
                    min_cost = cost;
                    arg = v;
                }
            }
            if (arg != out.label[f]) {
                out.label[f] = arg;
                ++changed;
            }
        }
        out.sweeps_run = sweep + 1;
        if (changed == 0) break;
    }
    for (int f = 0; f < nf; ++f) {
        if (out.label[f] < 0) ++out.unseen;
        if (out.label[f] != initial[f]) ++out.relabelled;
    }
    return out;
}

}  // namespace rgbd::texture
