#include "algorithms/texture/photo_consistency.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>

#include "toolkit/error.hpp"

namespace rgbd::texture {

void ConsistencyOptions::check() const {
    RGBD_CHECK(min_views >= 3 && min_views <= 1000,
               "texture: photo-consistency needs min_views in [3, 1000]");
    RGBD_CHECK(std::isfinite(max_levels) && max_levels > 0,
               "texture: photo-consistency threshold must be > 0 levels");
}

std::size_t reject_inconsistent_views(const render::RenderScene& scene,
                                      const std::vector<TextureView>& views,
                                      const std::vector<ColourGain>& gains,
                                      const ConsistencyOptions& options, FaceQuality& quality,
                                      Report& report) {
    options.check();
    const int nv = quality.views, nf = quality.faces;
    RGBD_CHECK(static_cast<int>(views.size()) == nv && static_cast<int>(gains.size()) == nv &&
                   static_cast<int>(scene.triangles().size()) == nf,
               "texture: photo-consistency inputs disagree in size");
    report["enabled"] = options.enabled;
    if (!options.enabled || nv < options.min_views) return 0;
    std::vector<Pose> camera_from_world(nv);
    for (int v = 0; v < nv; ++v) camera_from_world[v] = views[v].world_from_camera.inverse();
    const auto& verts = scene.vertices();
    const auto& tris = scene.triangles();
    std::atomic<std::size_t> checked{0};
    std::vector<std::atomic<std::size_t>> rejected(nv);
    tbb::parallel_for(
        tbb::blocked_range<int>(0, nf, 2048), [&](const tbb::blocked_range<int>& range) {
            std::vector<int> cand;
            std::vector<Eigen::Vector3d> colour;
            std::vector<double> channel;
            std::size_t local_checked = 0;
            for (int f = range.begin(); f != range.end(); ++f) {
                cand.clear();
                for (int v = 0; v < nv; ++v)
                    if (quality.at(v, f) > 0) cand.push_back(v);
                if (static_cast<int>(cand.size()) < options.min_views) continue;
                ++local_checked;
                const auto& t = tris[f];
                const Eigen::Vector3d c = (verts[t[0]] + verts[t[1]] + verts[t[2]]) / 3.0;
                const Eigen::Vector3d points[4] = {c, (2.0 * verts[t[0]] + c) / 3.0,
                                                   (2.0 * verts[t[1]] + c) / 3.0,
                                                   (2.0 * verts[t[2]] + c) / 3.0};
                colour.assign(cand.size(), Eigen::Vector3d::Zero());
                for (std::size_t i = 0; i < cand.size(); ++i) {
                    const TextureView& view = views[cand[i]];
                    for (const auto& p : points) {
                        const Eigen::Vector2d uv =
                            view.intrinsics.project(camera_from_world[cand[i]] * p);
                        colour[i] += sample_bgr(view.image, uv.x(), uv.y());
                    }
                    colour[i] = adjusted(gains[cand[i]], colour[i] / 4.0);
                }
                Eigen::Vector3d median;
                for (int ch = 0; ch < 3; ++ch) {
                    channel.clear();
                    for (const auto& col : colour) channel.push_back(col[ch]);
                    const std::size_t mid = channel.size() / 2;
                    std::nth_element(channel.begin(), channel.begin() + mid, channel.end());
                    median[ch] = channel[mid];
                    if (channel.size() % 2 == 0)
                        median[ch] = 0.5 * (median[ch] + *std::max_element(channel.begin(),
                                                                           channel.begin() + mid));
                }
                std::size_t closest = 0;
                for (std::size_t i = 1; i < cand.size(); ++i)
                    if ((colour[i] - median).norm() < (colour[closest] - median).norm())
                        closest = i;
                for (std::size_t i = 0; i < cand.size(); ++i)
                    if (i != closest && (colour[i] - median).norm() > options.max_levels) {
                        quality.quality[static_cast<std::size_t>(cand[i]) * nf + f] = 0.0f;
                        ++rejected[cand[i]];
                    }
            }
            checked += local_checked;
        });
    std::size_t total = 0;
    Report per_view = Report::array();
    for (int v = 0; v < nv; ++v) {
        total += rejected[v];
        per_view.push_back({{"view", views[v].name}, {"rejected_faces", rejected[v].load()}});
    }
    report["faces_checked"] = checked.load();
    report["rejected_pairs"] = total;
    report["views"] = per_view;
    return total;
}

}  // namespace rgbd::texture
