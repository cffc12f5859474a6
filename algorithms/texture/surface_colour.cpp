#include "algorithms/texture/surface_colour.hpp"

#include <tbb/parallel_for.h>

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "toolkit/error.hpp"

namespace rgbd::texture {
namespace {

/// Bilinear BGR lookup at texture coordinate uv (glTF convention), clamped to the edge.
Eigen::Vector3d texel(const cv::Mat& atlas, const Eigen::Vector2d& uv) {
    const double x = uv.x() * atlas.cols - 0.5, y = uv.y() * atlas.rows - 0.5;
    const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
    const double fx = x - x0, fy = y - y0;
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
            const double w = (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy);
            const cv::Vec3b& p = atlas.at<cv::Vec3b>(std::clamp(y0 + dy, 0, atlas.rows - 1),
                                                     std::clamp(x0 + dx, 0, atlas.cols - 1));
            c += w * Eigen::Vector3d(p[0], p[1], p[2]);
        }
    return c;
}

struct Sums {
    double sse = 0, sae = 0;
    std::size_t pixels = 0;
};

Sums compare_view(const TexturedMesh& model, const render::RenderScene& scene,
                  const TextureView& view, const ColourErrorOptions& options) {
    const PinholeIntrinsics& k = view.intrinsics;
    const render::DepthRender r = render::render_depth(scene, k, view.world_from_camera);
    cv::Mat mask = r.triangle >= 0;
    if (options.erode_px > 0)
        cv::erode(mask, mask,
                  cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * options.erode_px + 1,
                                                                     2 * options.erode_px + 1)));
    const Pose camera_from_world = view.world_from_camera.inverse();
    std::vector<Sums> rows(k.height);
    tbb::parallel_for(0, k.height, [&](int row) {
        Sums& s = rows[row];
        for (int col = 0; col < k.width; ++col) {
            if (!mask.at<uchar>(row, col)) continue;
            const int t = r.triangle.at<int>(row, col);
            const double z = r.depth.at<double>(row, col);
            const cv::Vec3f n = r.normal.at<cv::Vec3f>(row, col);
            const Eigen::Vector3d ray = k.unproject(col, row, 1.0).normalized();
            if (!std::isfinite(z) ||
                -(n[0] * ray.x() + n[1] * ray.y() + n[2] * ray.z()) < options.min_cos)
                continue;
            // Barycentric coordinates of the seen point on triangle t (camera frame).
            const Eigen::Vector3d p = k.unproject(col, row, z);
            const auto& f = model.faces[t];
            const Eigen::Vector3d a = camera_from_world * model.vertices[f[0]];
            const Eigen::Vector3d b = camera_from_world * model.vertices[f[1]];
            const Eigen::Vector3d c = camera_from_world * model.vertices[f[2]];
            const Eigen::Vector3d nn = (b - a).cross(c - a);
            const double area = nn.squaredNorm();
            if (!(area > 0)) continue;
            double w1 = (p - a).cross(c - a).dot(nn) / area;
            double w2 = (b - a).cross(p - a).dot(nn) / area;
            w1 = std::clamp(w1, 0.0, 1.0);
            w2 = std::clamp(w2, 0.0, 1.0 - w1);
            const double w0 = 1.0 - w1 - w2;
            Eigen::Vector3d colour;  // BGR
            if (model.has_texture()) {
                const auto& fu = model.face_uvs[t];
                const Eigen::Vector2d uv = w0 * model.uvs[fu[0]].cast<double>() +
                                           w1 * model.uvs[fu[1]].cast<double>() +
                                           w2 * model.uvs[fu[2]].cast<double>();
                colour = texel(model.atlases[model.face_atlas[t]], uv);
            } else {
                colour.setZero();
                const double w[3] = {w0, w1, w2};
                for (int j = 0; j < 3; ++j) {
                    const Rgb& q = model.vertex_colors[f[j]];
                    colour += w[j] * Eigen::Vector3d(q.b, q.g, q.r);
                }
            }
            const cv::Vec3b& m = view.image.at<cv::Vec3b>(row, col);
            for (int ch = 0; ch < 3; ++ch) {
                const double d = std::round(colour[ch]) - m[ch];
                s.sse += d * d;
                s.sae += std::abs(d);
            }
            ++s.pixels;
        }
    });
    Sums total;
    for (const auto& s : rows) {
        total.sse += s.sse;
        total.sae += s.sae;
        total.pixels += s.pixels;
    }
    return total;
}

void fill(const Sums& s, double& psnr, double& mae, double& rmse) {
    const double n = 3.0 * std::max<std::size_t>(s.pixels, 1);
    const double mse = s.sse / n;
    rmse = std::sqrt(mse);
    mae = s.sae / n;
    psnr = mse > 0 ? 10.0 * std::log10(255.0 * 255.0 / mse) : 99.0;
}

}  // namespace

void ColourErrorOptions::check() const {
    RGBD_CHECK(erode_px >= 0 && erode_px <= 100, "colour error: erode_px must be in [0, 100]");
    RGBD_CHECK(std::isfinite(min_cos) && min_cos >= 0 && min_cos < 1,
               "colour error: min_cos must be in [0, 1)");
}

ColourError surface_colour_error(const TexturedMesh& model, const std::vector<TextureView>& views,
                                 const ColourErrorOptions& options) {
    options.check();
    RGBD_CHECK(model.has_texture() || model.vertex_colors.size() == model.vertices.size(),
               "the model has neither a texture nor vertex colours");
    RGBD_CHECK(!views.empty(), "no colour images to compare with");
    const render::RenderScene scene(model.vertices, model.faces);
    ColourError out;
    Sums total;
    Report per_view = Report::array();
    for (const auto& view : views) {
        RGBD_CHECK(!view.image.empty() && view.image.cols == view.intrinsics.width &&
                       view.image.rows == view.intrinsics.height,
                   view.name + ": colour image missing or not of the colour camera's size");
        const Sums s = compare_view(model, scene, view, options);
        total.sse += s.sse;
        total.sae += s.sae;
        total.pixels += s.pixels;
        double psnr, mae, rmse;
        fill(s, psnr, mae, rmse);
        per_view.push_back({{"view", view.name},
                            {"pixels", s.pixels},
                            {"psnr_db", s.pixels ? psnr : 0.0},
                            {"mae", mae}});
    }
    RGBD_CHECK(total.pixels > 0, "no colour camera sees the model's surface");
    out.pixels = total.pixels;
    fill(total, out.psnr_db, out.mae, out.rmse);
    out.report = {{"pixels", out.pixels},
                  {"psnr_db", out.psnr_db},
                  {"mae", out.mae},
                  {"rmse", out.rmse},
                  {"source", model.has_texture() ? "texture" : "vertex colours"},
                  {"erode_px", options.erode_px},
                  {"min_cos", options.min_cos},
                  {"views", per_view}};
    return out;
}

}  // namespace rgbd::texture
