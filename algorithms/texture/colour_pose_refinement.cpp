#include "algorithms/texture/colour_pose_refinement.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <string>

#include "toolkit/error.hpp"

namespace rgbd::texture {
namespace {

constexpr double kDeg = M_PI / 180.0;

/// The grey images of every view at one pyramid level: value and gradient (per pixel of the
/// level), and the intrinsics of the level.
struct Level {
    std::vector<cv::Mat> grey, gx, gy;  // CV_32F, grey level / 255
    std::vector<PinholeIntrinsics> k;
};

Level make_level(const std::vector<TextureView>& views, int level, double blur_px) {
    Level out;
    const std::size_t n = views.size();
    out.grey.resize(n);
    out.gx.resize(n);
    out.gy.resize(n);
    out.k.resize(n);
    tbb::parallel_for(std::size_t{0}, n, [&](std::size_t c) {
        cv::Mat grey;
        cv::cvtColor(views[c].image, grey, cv::COLOR_BGR2GRAY);
        grey.convertTo(grey, CV_32F, 1.0 / 255.0);
        PinholeIntrinsics k = views[c].intrinsics;
        for (int l = 0; l < level; ++l) {
            cv::pyrDown(grey, grey);
            // Pixel centres at integers: u' = (u + 0.5) / 2 - 0.5.
            k.fx *= 0.5;
            k.fy *= 0.5;
            k.cx = (k.cx + 0.5) * 0.5 - 0.5;
            k.cy = (k.cy + 0.5) * 0.5 - 0.5;
        }
        k.width = grey.cols;
        k.height = grey.rows;
        if (blur_px > 0) cv::GaussianBlur(grey, grey, cv::Size(0, 0), blur_px);
        cv::Sobel(grey, out.gx[c], CV_32F, 1, 0, 3, 1.0 / 8.0);
        cv::Sobel(grey, out.gy[c], CV_32F, 0, 1, 3, 1.0 / 8.0);
        out.grey[c] = grey;
        out.k[c] = k;
    });
    return out;
}

/// Bilinear value of a CV_32F image at (u, v); false outside [0, size - 1).
bool bilinear(const cv::Mat& m, double u, double v, double& value) {
    if (!(u >= 0 && v >= 0 && u < m.cols - 1 && v < m.rows - 1)) return false;
    const int c = static_cast<int>(u), r = static_cast<int>(v);
    const double a = u - c, b = v - r;
    const float* r0 = m.ptr<float>(r);
    const float* r1 = m.ptr<float>(r + 1);
    value = (1 - b) * ((1 - a) * r0[c] + a * r0[c + 1]) + b * ((1 - a) * r1[c] + a * r1[c + 1]);
    return true;
}

/// Points on the mesh's faces (a barycentric grid of n^2 points per face, n from the longest
/// edge over the spacing) and their face normals.
struct Samples {
    std::vector<Eigen::Vector3d> p, n;
    double spacing = 0;
};

Samples sample_mesh(const render::RenderScene& scene, const std::vector<TextureView>& views,
                    const RefineOptions& options) {
    const auto& verts = scene.vertices();
    const auto& tris = scene.triangles();
    Samples out;
    out.spacing = options.sample_spacing_m;
    if (out.spacing <= 0) {
        // The median footprint of a colour pixel at the distance of the mesh's centre.
        Eigen::Vector3d centre = Eigen::Vector3d::Zero();
        for (const auto& v : verts) centre += v;
        centre /= static_cast<double>(verts.size());
        std::vector<double> footprint;
        for (const auto& v : views)
            footprint.push_back((v.world_from_camera.translation() - centre).norm() /
                                v.intrinsics.fx);
        std::nth_element(footprint.begin(), footprint.begin() + footprint.size() / 2,
                         footprint.end());
        out.spacing = std::max(footprint[footprint.size() / 2], 1e-5);
    }
    auto count = [&](double spacing, std::vector<int>* per_face) {
        double total = 0;
        for (std::size_t f = 0; f < tris.size(); ++f) {
            const auto& t = tris[f];
            const double e =
                std::max({(verts[t[0]] - verts[t[1]]).norm(), (verts[t[1]] - verts[t[2]]).norm(),
                          (verts[t[2]] - verts[t[0]]).norm()});
            const int n = std::clamp(static_cast<int>(std::ceil(e / spacing)), 1, 64);
            if (per_face) (*per_face)[f] = n;
            total += static_cast<double>(n) * n;
        }
        return total;
    };
    for (int round = 0; round < 20; ++round) {
        const double total = count(out.spacing, nullptr);
        if (total <= options.max_samples) break;
        out.spacing *= std::max(1.05, std::sqrt(total / options.max_samples));
    }
    std::vector<int> per_face(tris.size(), 1);
    count(out.spacing, &per_face);
    for (std::size_t f = 0; f < tris.size(); ++f) {
        const Eigen::Vector3d& normal = scene.normals()[f];
        if (normal.isZero()) continue;
        const auto& t = tris[f];
        const Eigen::Vector3d &a = verts[t[0]], &b = verts[t[1]], &c = verts[t[2]];
        const int n = per_face[f];
        auto add = [&](double i, double j) {
            const double s = i / n, r = j / n;
            out.p.push_back(a + s * (b - a) + r * (c - a));
            out.n.push_back(normal);
        };
        for (int i = 0; i < n; ++i)
            for (int j = 0; i + j < n; ++j) {
                add(i + 1.0 / 3.0, j + 1.0 / 3.0);  // upright sub-triangle
                if (i + j + 1 < n) add(i + 2.0 / 3.0, j + 2.0 / 3.0);
            }
    }
    return out;
}

/// Per camera, the points it sees at `level` with poses camera_from_world `pose`; only points
/// seen by at least two cameras are kept.
std::vector<std::vector<int>> visibility(const render::RenderScene& scene, const Samples& samples,
                                         const Level& level, const std::vector<Pose>& pose,
                                         const RefineOptions& options) {
    const int nc = static_cast<int>(pose.size());
    const int np = static_cast<int>(samples.p.size());
    std::vector<std::vector<int>> vis(nc);
    tbb::parallel_for(0, nc, [&](int c) {
        const PinholeIntrinsics& k = level.k[c];
        const Pose world_from_camera = pose[c].inverse();
        const render::DepthRender render = render::render_depth(scene, k, world_from_camera);
        // Depth jumps: max - min of the depth (no surface = far) over a window.
        cv::Mat d = render.depth_float();
        cv::patchNaNs(d, 1e3);
        cv::Mat dmax, dmin;
        const cv::Mat kernel = cv::getStructuringElement(
            cv::MORPH_RECT, cv::Size(2 * options.edge_px + 1, 2 * options.edge_px + 1));
        cv::dilate(d, dmax, kernel);
        cv::erode(d, dmin, kernel);
        const Eigen::Vector3d centre = world_from_camera.translation();
        const double border = options.edge_px + 1;
        for (int i = 0; i < np; ++i) {
            const Eigen::Vector3d& p = samples.p[i];
            if (!(samples.n[i].dot((centre - p).normalized()) >= options.min_cos)) continue;
            const Eigen::Vector3d q = pose[c] * p;
            if (!(q.z() > 0.05)) continue;
            const Eigen::Vector2d uv = k.project(q);
            if (!(uv.x() >= border && uv.y() >= border && uv.x() <= k.width - 1 - border &&
                  uv.y() <= k.height - 1 - border))
                continue;
            const int col = static_cast<int>(std::lround(uv.x())),
                      row = static_cast<int>(std::lround(uv.y()));
            const double z = render.depth.at<double>(row, col);
            if (!std::isfinite(z) ||
                dmax.at<float>(row, col) - dmin.at<float>(row, col) > options.edge_jump_m)
                continue;
            if (q.z() > z + options.depth_tolerance_m + options.depth_tolerance_rel * q.z())
                continue;
            vis[c].push_back(i);
        }
    });
    std::vector<int> seen(np, 0);
    for (const auto& list : vis)
        for (const int i : list) ++seen[i];
    for (auto& list : vis)
        list.erase(std::remove_if(list.begin(), list.end(), [&](int i) { return seen[i] < 2; }),
                   list.end());
    return vis;
}

/// The proxy colours C(p): the mean grey level of the cameras seeing p (NaN where fewer than
/// two cameras have it inside their image).
std::vector<double> proxy_colours(const Samples& samples, const Level& level,
                                  const std::vector<std::vector<int>>& vis,
                                  const std::vector<Pose>& pose) {
    const std::size_t nc = vis.size(), np = samples.p.size();
    std::vector<std::vector<float>> value(nc);
    tbb::parallel_for(std::size_t{0}, nc, [&](std::size_t c) {
        value[c].resize(vis[c].size());
        for (std::size_t j = 0; j < vis[c].size(); ++j) {
            const Eigen::Vector2d uv = level.k[c].project(pose[c] * samples.p[vis[c][j]]);
            double g = 0;
            value[c][j] = bilinear(level.grey[c], uv.x(), uv.y(), g)
                              ? static_cast<float>(g)
                              : std::numeric_limits<float>::quiet_NaN();
        }
    });
    std::vector<double> sum(np, 0.0);
    std::vector<int> n(np, 0);
    for (std::size_t c = 0; c < nc; ++c)
        for (std::size_t j = 0; j < vis[c].size(); ++j)
            if (!std::isnan(value[c][j])) {
                sum[vis[c][j]] += value[c][j];
                ++n[vis[c][j]];
            }
    std::vector<double> colour(np, std::numeric_limits<double>::quiet_NaN());
    for (std::size_t i = 0; i < np; ++i)
        if (n[i] >= 2) colour[i] = sum[i] / n[i];
    return colour;
}

/// One camera's normal equations at its pose (left perturbation exp(xi) T, xi = (omega, v) in
/// the camera frame), with Huber weights: H, g and the sum of squared residuals over n points.
struct Normal {
    Eigen::Matrix<double, 6, 6> h = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
    double sq = 0;
    std::size_t n = 0;
};

Normal normal_equations(const Samples& samples, const Level& level, int c,
                        const std::vector<int>& vis, const std::vector<double>& colour,
                        const Pose& pose, double huber) {
    Normal out;
    const PinholeIntrinsics& k = level.k[c];
    for (const int i : vis) {
        if (std::isnan(colour[i])) continue;
        const Eigen::Vector3d q = pose * samples.p[i];
        const Eigen::Vector2d uv = k.project(q);
        double value = 0, gx = 0, gy = 0;
        if (!bilinear(level.grey[c], uv.x(), uv.y(), value) ||
            !bilinear(level.gx[c], uv.x(), uv.y(), gx) ||
            !bilinear(level.gy[c], uv.x(), uv.y(), gy))
            continue;
        const double r = value - colour[i];
        const double iz = 1.0 / q.z();
        // d(residual)/dq: the image gradient through the projection.
        const Eigen::Vector3d jq(gx * k.fx * iz, gy * k.fy * iz,
                                 -(gx * k.fx * q.x() + gy * k.fy * q.y()) * iz * iz);
        Eigen::Matrix<double, 6, 1> j;
        j << q.cross(jq), jq;
        const double w = std::abs(r) <= huber ? 1.0 : huber / std::abs(r);
        out.h.noalias() += w * j * j.transpose();
        out.g.noalias() += w * r * j;
        out.sq += r * r;
        ++out.n;
    }
    return out;
}

/// exp(xi) (first order in the translation: a retraction with the same derivative at 0).
Pose exp_pose(const Eigen::Matrix<double, 6, 1>& xi) {
    Pose out = Pose::Identity();
    const Eigen::Vector3d w = xi.head<3>();
    if (w.norm() > 0) out.linear() = Eigen::AngleAxisd(w.norm(), w.normalized()).matrix();
    out.translation() = xi.tail<3>();
    return out;
}

/// The (omega, v) of the pose camera_new_from_camera_old = pose * initial^-1.
Eigen::Matrix<double, 6, 1> log_pose(const Pose& pose, const Pose& initial) {
    const Pose d = pose * initial.inverse();
    const Eigen::AngleAxisd aa(d.rotation());
    Eigen::Matrix<double, 6, 1> xi;
    xi << aa.angle() * aa.axis(), d.translation();
    return xi;
}

/// RMS residual (levels 0-255) per camera and over all pairs, at `level` with poses `pose`
/// (visibility and proxy colours computed for these poses).
struct Residual {
    std::vector<double> rms;
    double total = 0;
    std::vector<std::size_t> n;
};

Residual residual(const render::RenderScene& scene, const Samples& samples, const Level& level,
                  const std::vector<Pose>& pose, const RefineOptions& options) {
    const auto vis = visibility(scene, samples, level, pose, options);
    const auto colour = proxy_colours(samples, level, vis, pose);
    Residual out;
    const std::size_t nc = pose.size();
    out.rms.assign(nc, 0.0);
    out.n.assign(nc, 0);
    std::vector<Normal> normal(nc);
    tbb::parallel_for(std::size_t{0}, nc, [&](std::size_t c) {
        normal[c] = normal_equations(samples, level, static_cast<int>(c), vis[c], colour, pose[c],
                                     options.huber);
    });
    double sq = 0;
    std::size_t n = 0;
    for (std::size_t c = 0; c < nc; ++c) {
        out.n[c] = normal[c].n;
        out.rms[c] = normal[c].n ? 255.0 * std::sqrt(normal[c].sq / normal[c].n) : 0.0;
        sq += normal[c].sq;
        n += normal[c].n;
    }
    out.total = n ? 255.0 * std::sqrt(sq / n) : 0.0;
    return out;
}

/// The Gauss-Newton iterations of one pyramid level; returns the number run.
int refine_level(const render::RenderScene& scene, const Samples& samples, const Level& level,
                 const std::vector<Pose>& initial, std::vector<Pose>& pose,
                 std::vector<char>& moved, const RefineOptions& options) {
    const int nc = static_cast<int>(pose.size());
    const auto vis = visibility(scene, samples, level, pose, options);
    int it = 0;
    for (; it < options.iterations; ++it) {
        const auto colour = proxy_colours(samples, level, vis, pose);
        std::vector<double> step_deg(nc, 0.0), step_mm(nc, 0.0);
        tbb::parallel_for(0, nc, [&](int c) {
            if (static_cast<int>(vis[c].size()) < options.min_samples) return;
            Normal ne = normal_equations(samples, level, c, vis[c], colour, pose[c], options.huber);
            if (static_cast<int>(ne.n) < options.min_samples) return;
            // The prior towards the initial pose, a Huber norm of the correction in units of
            // 0.01 degree and 0.1 mm: stiff at 0 (1 degree costs as much as one grey level at
            // every point the camera sees), so that the cameras whose pose is right hold the
            // motions that the photometric cost does not see, but beyond it a constant pull
            // (a hundredth of a grey level per degree or per 10 mm at every point), which
            // hardly biases a camera whose pose is off.
            const double sigma_rot = 0.01 * kDeg, sigma_t = 1e-4;
            const double kappa = 1e-4 * static_cast<double>(ne.n) / (255.0 * 255.0);
            const Eigen::Matrix<double, 6, 1> xi0 = log_pose(pose[c], initial[c]);
            const double d =
                std::hypot(xi0.head<3>().norm() / sigma_rot, xi0.tail<3>().norm() / sigma_t);
            const double weight = kappa * (d <= 1 ? 1.0 : 1.0 / d);
            // Plus a quadratic term for the weakly observed directions (a shift along the
            // optical axis changes the image only by its scale): 1 degree or 10 mm cost
            // `prior_levels` grey levels at every point.
            const double quad = options.prior_levels * options.prior_levels *
                                static_cast<double>(ne.n) / (255.0 * 255.0);
            Eigen::Matrix<double, 6, 1> prior;
            prior << Eigen::Vector3d::Constant(weight / (sigma_rot * sigma_rot) +
                                               quad / (kDeg * kDeg)),
                Eigen::Vector3d::Constant(weight / (sigma_t * sigma_t) + quad / (0.01 * 0.01));
            ne.h.diagonal() += prior;
            ne.g += prior.cwiseProduct(xi0);
            // Levenberg-Marquardt damping, light: the Huber weights already bound outliers.
            ne.h.diagonal() *= 1.0 + 1e-4;
            Eigen::Matrix<double, 6, 1> xi = -ne.h.ldlt().solve(ne.g);
            if (!xi.allFinite()) return;
            // At most 0.5 degree and 5 mm per step.
            const double scale = std::min({1.0, 0.5 * kDeg / std::max(xi.head<3>().norm(), 1e-12),
                                           0.005 / std::max(xi.tail<3>().norm(), 1e-12)});
            xi *= scale;
            pose[c] = exp_pose(xi) * pose[c];
            moved[c] = 1;
            step_deg[c] = xi.head<3>().norm() / kDeg;
            step_mm[c] = xi.tail<3>().norm() * 1000.0;
        });
        if (*std::max_element(step_deg.begin(), step_deg.end()) < 1e-3 &&
            *std::max_element(step_mm.begin(), step_mm.end()) < 1e-2) {
            ++it;
            break;
        }
    }
    return it;
}

}  // namespace

void RefineOptions::check() const {
    RGBD_CHECK(iterations >= 1 && iterations <= 1000,
               "texture: colour refinement iterations must be in [1, 1000]");
    RGBD_CHECK(levels >= 1 && levels <= 6, "texture: colour refinement levels must be in [1, 6]");
    RGBD_CHECK(std::isfinite(min_cos) && min_cos >= 0 && min_cos < 1,
               "texture: colour refinement min_cos must be in [0, 1)");
    RGBD_CHECK(std::isfinite(blur_px) && blur_px >= 0 && blur_px <= 20,
               "texture: colour refinement blur must be in [0, 20] px");
    RGBD_CHECK(std::isfinite(depth_tolerance_m) && depth_tolerance_m >= 0 &&
                   depth_tolerance_m <= 1 && std::isfinite(depth_tolerance_rel) &&
                   depth_tolerance_rel >= 0 && depth_tolerance_rel <= 1,
               "texture: colour refinement depth tolerances must be in [0, 1]");
    RGBD_CHECK(edge_px >= 0 && edge_px <= 50 && std::isfinite(edge_jump_m) && edge_jump_m > 0,
               "texture: colour refinement edge window must be in [0, 50] px, jump > 0 m");
    RGBD_CHECK(std::isfinite(prior_levels) && prior_levels >= 0 && prior_levels <= 255,
               "texture: colour refinement prior must be in [0, 255] grey levels");
    RGBD_CHECK(std::isfinite(huber) && huber > 0,
               "texture: colour refinement Huber threshold must be > 0");
    RGBD_CHECK(std::isfinite(max_rotation_deg) && max_rotation_deg > 0 && max_rotation_deg <= 45,
               "texture: colour refinement largest rotation must be in (0, 45] degrees");
    RGBD_CHECK(std::isfinite(max_translation_m) && max_translation_m > 0 && max_translation_m <= 1,
               "texture: colour refinement largest translation must be in (0, 1] m");
    RGBD_CHECK(std::isfinite(sample_spacing_m) && sample_spacing_m >= 0 && sample_spacing_m <= 1,
               "texture: colour refinement sample spacing must be in [0, 1] m");
    RGBD_CHECK(max_samples >= 1000 && max_samples <= 50000000,
               "texture: colour refinement samples must be in [1000, 5e7]");
    RGBD_CHECK(min_samples >= 6 && min_samples <= 10000000,
               "texture: colour refinement min_samples must be in [6, 1e7]");
}

std::vector<Pose> refine_colour_poses(const render::RenderScene& scene,
                                      const std::vector<TextureView>& views,
                                      const RefineOptions& options, Report& report) {
    options.check();
    Stopwatch watch;
    for (const auto& v : views) {
        v.intrinsics.check();
        RGBD_CHECK(!v.image.empty() && v.image.type() == CV_8UC3 &&
                       v.image.cols == v.intrinsics.width && v.image.rows == v.intrinsics.height,
                   v.name + ": colour image missing or not of the colour camera's size");
    }
    const std::size_t nc = views.size();
    std::vector<Pose> initial(nc);
    for (std::size_t c = 0; c < nc; ++c) initial[c] = views[c].world_from_camera.inverse();
    std::vector<Pose> pose = initial;
    const Samples samples = sample_mesh(scene, views, options);
    report["samples"] = samples.p.size();
    report["sample_spacing_mm"] = samples.spacing * 1000.0;
    Report iterations = Report::array();
    Level finest;
    std::vector<char> moved(nc, 0);
    for (int l = options.levels - 1; l >= 0; --l) {
        Level level = make_level(views, l, options.blur_px);
        iterations.push_back(refine_level(scene, samples, level, initial, pose, moved, options));
        if (l == 0) finest = std::move(level);
    }
    report["iterations"] = iterations;  // per level, coarse to fine
    const Residual before = residual(scene, samples, finest, initial, options);
    Residual after = residual(scene, samples, finest, pose, options);

    // Refusals: absurd corrections, or no decrease of the camera's residual.
    std::vector<Pose> out(nc);
    Report cameras = Report::array();
    int refused = 0, refined = 0;
    std::vector<std::string> status(nc), reason(nc);
    std::vector<double> rot_deg(nc), shift_mm(nc);
    for (std::size_t c = 0; c < nc; ++c) {
        const Pose world_from_new = pose[c].inverse();
        rot_deg[c] = rotation_error_deg(world_from_new, views[c].world_from_camera);
        shift_mm[c] = 1000.0 * translation_error_m(world_from_new, views[c].world_from_camera);
        out[c] = world_from_new;
        status[c] = "refined";
        if (!moved[c]) {
            out[c] = views[c].world_from_camera;
            rot_deg[c] = shift_mm[c] = 0;
            status[c] = "unchanged";
            reason[c] = "fewer than " + std::to_string(options.min_samples) +
                        " points shared with other cameras";
        } else if (rot_deg[c] > options.max_rotation_deg ||
                   shift_mm[c] > options.max_translation_m * 1000.0) {
            status[c] = "refused";
            char text[160];
            std::snprintf(text, sizeof text,
                          "correction of %.2f degrees / %.1f mm exceeds %.2f degrees / %.1f mm",
                          rot_deg[c], shift_mm[c], options.max_rotation_deg,
                          options.max_translation_m * 1000.0);
            reason[c] = text;
        } else if (after.n[c] == 0 || after.rms[c] >= before.rms[c]) {
            status[c] = "refused";
            reason[c] = "the photometric residual does not decrease";
        }
        if (status[c] == "refused") {
            out[c] = views[c].world_from_camera;
            pose[c] = initial[c];
            ++refused;
        } else if (status[c] == "refined") {
            ++refined;
        }
    }
    if (refused > 0) after = residual(scene, samples, finest, pose, options);
    for (std::size_t c = 0; c < nc; ++c) {
        Report row{{"view", views[c].name},         {"status", status[c]},
                   {"rotation_deg", rot_deg[c]},    {"translation_mm", shift_mm[c]},
                   {"points", before.n[c]},         {"residual_before", before.rms[c]},
                   {"residual_after", after.rms[c]}};
        if (!reason[c].empty()) row["reason"] = reason[c];
        const auto m = pose_to_3x4(out[c]);
        row["world_from_camera"] = std::vector<double>(m.begin(), m.end());
        cameras.push_back(row);
    }
    report["residual_before"] = before.total;
    report["residual_after"] = after.total;
    report["refined"] = refined;
    report["refused"] = refused;
    report["cameras"] = cameras;
    report["time_s"] = watch.seconds();
    return out;
}

}  // namespace rgbd::texture
