// §12 large holes and the body axis: see large_holes.hpp.
#include "algorithms/holes/large_holes.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <opencv2/imgproc.hpp>

#include "algorithms/holes/inpaint_common.hpp"
#include "toolkit/error.hpp"

namespace rgbd::holes {

using namespace detail;

BodyAxis estimate_body_axis(const SurfacePoints& points, const std::vector<SensorView>& sensors) {
    RGBD_CHECK(!points.position.empty(), "body axis: no points");
    BodyAxis axis;
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const auto& p : points.position) centroid += p;
    centroid /= double(points.size());
    axis.origin = centroid;
    if (sensors.size() >= 3) {
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        for (const auto& s : sensors) mean += s.world_from_sensor.translation();
        mean /= double(sensors.size());
        Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
        Eigen::Vector3d camera_up = Eigen::Vector3d::Zero();
        for (const auto& s : sensors) {
            const Eigen::Vector3d d = s.world_from_sensor.translation() - mean;
            cov += d * d.transpose();
            camera_up -= s.world_from_sensor.linear().col(1);  // image y points down
        }
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
        const Eigen::Vector3d l = eig.eigenvalues();
        // A plane: the two larger spreads comparable, the smallest one much smaller.
        if (l[1] > 1e-6 && l[0] < 0.05 * l[1] && camera_up.norm() > 1e-9) {
            axis.up = eig.eigenvectors().col(0).normalized();
            if (axis.up.dot(camera_up) < 0) axis.up = -axis.up;
            axis.from_sensors = true;
            return axis;
        }
    }
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const auto& p : points.position) {
        const Eigen::Vector3d d = p - centroid;
        cov += d * d.transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    Eigen::Vector3d up = eig.eigenvectors().col(2).normalized();
    // The narrower end is the top: mean distance from the axis in the top and bottom tenths.
    std::vector<double> h;
    h.reserve(points.size());
    for (const auto& p : points.position) h.push_back((p - centroid).dot(up));
    std::vector<double> sorted = h;
    std::sort(sorted.begin(), sorted.end());
    const double lo = sorted[sorted.size() / 10], hi = sorted[sorted.size() * 9 / 10];
    double width_lo = 0, width_hi = 0;
    std::size_t n_lo = 0, n_hi = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
        const Eigen::Vector3d d = points.position[i] - centroid;
        const double w = (d - h[i] * up).norm();
        if (h[i] <= lo) width_lo += w, ++n_lo;
        if (h[i] >= hi) width_hi += w, ++n_hi;
    }
    if (n_lo && n_hi && width_hi / n_hi > width_lo / n_lo) up = -up;
    axis.up = up;
    return axis;
}

namespace {

/// Pads a map of the cylinder image's width with `pad` columns each side, copied across the
/// seam (theta wraps).
cv::Mat wrap_pad(const cv::Mat& img, int pad) {
    cv::Mat out;
    cv::copyMakeBorder(img, out, 0, 0, std::min(pad, img.cols), std::min(pad, img.cols),
                       cv::BORDER_WRAP);
    return out;
}

/// §12.1 steps 2-4: the points unrolled onto a cylinder around the body axis. Pixel (r, c)
/// spans `px` metres of height from `h_min` and `dtheta` radians of angle from -pi (theta from
/// e1 towards e2); it holds the largest radius that falls in it (the outer surface, -1 where
/// none: `known` is 0), with that point's colour and its normal's radial component.
struct CylinderImage {
    Eigen::Vector3d e1, e2;
    double px = 0, dtheta = 0, h_min = 0;
    int rows = 0, cols = 0;
    cv::Mat radius, color, radial, known;
};

/// Builds the cylinder image: a column spans an angle sized for the 10th-percentile radius,
/// a row `options.pixel` spacings of height. AlgorithmError when it would exceed 64 M pixels.
CylinderImage unroll_on_cylinder(const SurfacePoints& points,
                                 const std::vector<Eigen::Vector3d>& normals, const BodyAxis& axis,
                                 double spacing_m, const InpaintOptions& options) {
    CylinderImage img;
    horizontal_frame(axis.up, img.e1, img.e2);
    const Eigen::Vector3d& up = axis.up;
    const std::size_t n = points.size();
    std::vector<double> theta(n), hh(n), rad(n);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1024), [&](const auto& range) {
        for (std::size_t i = range.begin(); i != range.end(); ++i) {
            const Eigen::Vector3d d = points.position[i] - axis.origin;
            const double x = d.dot(img.e1), y = d.dot(img.e2);
            theta[i] = std::atan2(y, x);
            hh[i] = d.dot(up);
            rad[i] = std::hypot(x, y);
        }
    });
    img.px = options.pixel * spacing_m;
    std::vector<double> sorted = rad;
    std::nth_element(sorted.begin(), sorted.begin() + n / 10, sorted.end());
    const double r10 = std::max(sorted[n / 10], img.px);
    img.h_min = *std::min_element(hh.begin(), hh.end());
    const double h_max = *std::max_element(hh.begin(), hh.end());
    img.rows = static_cast<int>(std::ceil((h_max - img.h_min) / img.px)) + 1;
    img.cols = std::max(8, static_cast<int>(std::ceil(2 * M_PI * r10 / img.px)));
    const int rows = img.rows, cols = img.cols;
    RGBD_CHECK_AS(AlgorithmError, double(cols) * rows < 64e6,
                  "large holes: the cylinder image would have " + std::to_string(cols) + " x " +
                      std::to_string(rows) + " pixels (spacing too small for the object?)");
    img.dtheta = 2 * M_PI / cols;
    img.radius = cv::Mat(rows, cols, CV_32F, cv::Scalar(-1.0f));
    img.color = cv::Mat(rows, cols, CV_8UC3, cv::Scalar(0, 0, 0));
    img.radial = cv::Mat(rows, cols, CV_32F, cv::Scalar(0.0f));
    for (std::size_t i = 0; i < n; ++i) {
        const int r = std::clamp(static_cast<int>((hh[i] - img.h_min) / img.px), 0, rows - 1);
        const int c = std::clamp(static_cast<int>((theta[i] + M_PI) / img.dtheta), 0, cols - 1);
        if (rad[i] <= img.radius.at<float>(r, c)) continue;
        img.radius.at<float>(r, c) = static_cast<float>(rad[i]);
        const Rgb col = points.color.empty() ? Rgb{128, 128, 128} : points.color[i];
        img.color.at<cv::Vec3b>(r, c) = {col.r, col.g, col.b};
        const Eigen::Vector3d d = points.position[i] - axis.origin;
        const Eigen::Vector3d out = (d - d.dot(up) * up).normalized();
        img.radial.at<float>(r, c) = static_cast<float>(normals[i].dot(out));
    }
    img.known = img.radius >= 0.0f;
    return img;
}

/// The hole components of a cylinder image: `labels` (8-connected, merged across the seam;
/// every hole pixel holds its component's label, 0 elsewhere), `fill` per label, and
/// `target` (255 on the pixels of the components to fill).
struct HoleComponents {
    cv::Mat labels, target;
    int n_labels = 0;
    std::vector<std::uint8_t> fill;

    void update_target() {
        target = cv::Mat(labels.size(), CV_8U, cv::Scalar(0));
        for (int r = 0; r < labels.rows; ++r)
            for (int c = 0; c < labels.cols; ++c) {
                const int l = labels.at<int>(r, c);
                if (l > 0 && fill[l]) target.at<std::uint8_t>(r, c) = 255;
            }
    }
};

/// Step 5 [M]: hole = unknown pixels between the lowest and the highest known pixel of their
/// column (the bottom cut and the top stay outside), below row `top_row` (the head top's
/// region); components of fewer than min_component pixels are left to §11, and a component
/// is kept only when at most max_open_rim of its edge borders the outside (the enclosure
/// test) and its rim normals point outward on average (the star-shape test). Reports the
/// skipped counts into `info`.
HoleComponents find_hole_components(const CylinderImage& img, int top_row,
                                    const InpaintOptions& options, Report& info) {
    const int rows = img.rows, cols = img.cols;
    const cv::Mat& known = img.known;
    cv::Mat hole(rows, cols, CV_8U, cv::Scalar(0));
    // Outside: below the lowest or above the highest known pixel of the column (the head top's
    // rows excepted), where no measured surface encloses an unknown pixel.
    cv::Mat outside(rows, cols, CV_8U, cv::Scalar(0));
    for (int c = 0; c < cols; ++c) {
        int lo = -1, hi = -1;
        for (int r = 0; r < rows; ++r)
            if (known.at<std::uint8_t>(r, c)) {
                if (lo < 0) lo = r;
                hi = r;
            }
        for (int r = lo + 1; r < std::min(hi, top_row + 1); ++r)
            if (!known.at<std::uint8_t>(r, c)) hole.at<std::uint8_t>(r, c) = 255;
        for (int r = 0; r < rows; ++r)
            if (lo < 0 || r < lo || (r > hi && r <= top_row)) outside.at<std::uint8_t>(r, c) = 255;
    }
    HoleComponents holes;
    cv::Mat& labels = holes.labels;
    const int n_labels = holes.n_labels = cv::connectedComponents(hole, labels, 8, CV_32S);
    // Merge labels across the seam (column 0 and column cols - 1 touch), then give every pixel
    // its component's root.
    std::vector<int> parent(n_labels);
    for (int l = 0; l < n_labels; ++l) parent[l] = l;
    std::function<int(int)> find = [&](int l) {
        return parent[l] == l ? l : parent[l] = find(parent[l]);
    };
    for (int r = 0; r < rows; ++r)
        for (int dr = -1; dr <= 1; ++dr) {
            const int r2 = r + dr;
            if (r2 < 0 || r2 >= rows) continue;
            const int a = labels.at<int>(r, 0), b = labels.at<int>(r2, cols - 1);
            if (a > 0 && b > 0) parent[find(a)] = find(b);
        }
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            int& l = labels.at<int>(r, c);
            if (l > 0) l = find(l);
        }
    std::vector<int> size(n_labels, 0);
    std::vector<double> rim_sum(n_labels, 0.0);
    std::vector<int> rim_count(n_labels, 0);
    std::vector<int> open_edges(n_labels, 0), closed_edges(n_labels, 0);
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            const int l = labels.at<int>(r, c);
            if (l > 0) {
                ++size[l];
                // Its 4-neighbours: measured (enclosed) or outside (the hole is a notch in the
                // open boundary of the surface).
                for (const auto& [dr, dc] : {std::pair{-1, 0}, {1, 0}, {0, -1}, {0, 1}}) {
                    const int r2 = r + dr, c2 = ((c + dc) % cols + cols) % cols;
                    if (r2 < 0 || r2 >= rows) continue;
                    if (outside.at<std::uint8_t>(r2, c2))
                        ++open_edges[l];
                    else if (known.at<std::uint8_t>(r2, c2))
                        ++closed_edges[l];
                }
                continue;
            }
            if (!known.at<std::uint8_t>(r, c)) continue;
            // A known pixel next to a hole pixel is on that hole's rim.
            int seen = -1;
            for (int dr = -1; dr <= 1; ++dr)
                for (int dc = -1; dc <= 1; ++dc) {
                    const int r2 = r + dr;
                    if (r2 < 0 || r2 >= rows) continue;
                    const int root = labels.at<int>(r2, ((c + dc) % cols + cols) % cols);
                    if (root <= 0 || root == seen) continue;
                    seen = root;
                    rim_sum[root] += img.radial.at<float>(r, c);
                    ++rim_count[root];
                }
        }
    holes.fill.assign(n_labels, 0);
    int filled = 0, too_small = 0, not_star = 0, not_enclosed = 0;
    for (int l = 1; l < n_labels; ++l) {
        if (find(l) != l || size[l] == 0) continue;
        if (size[l] < options.min_component) {
            ++too_small;
            continue;
        }
        if (open_edges[l] > options.max_open_rim * (open_edges[l] + closed_edges[l])) {
            ++not_enclosed;
            continue;
        }
        if (rim_count[l] == 0 || rim_sum[l] / rim_count[l] < options.min_rim_radial) {
            ++not_star;
            continue;
        }
        holes.fill[l] = 1;
        ++filled;
    }
    holes.update_target();
    info["skipped_small"] = too_small;
    info["skipped_not_star_shaped"] = not_star;
    info["skipped_not_enclosed"] = not_enclosed;
    return holes;
}

/// [M] Step test: a hole is filled only where its two sides predict the same surface. Along
/// every column, the measured radius below and above a run of hole pixels, each continued
/// across the run by its own slope (the mean over up to four measured rows), must meet; the
/// RMS of the mismatch over the hole's columns, in spacings, must not exceed max_step_rms.
/// A hole behind an occluding edge fails it: under a chin, or in the recess above a bust's
/// base, the rims are two surfaces at different radii, and the surface that the inpainting
/// bridges them with lies in the air (2.7-6.7% of the points inpainted there were 5-14 mm off
/// the truth, validation/results/2026-11-25-ablation-seeds-a2a70c2.md). The mesher's faired
/// patch is the better guess there. Returns the number of components dropped.
int apply_step_test(const CylinderImage& img, HoleComponents& holes, double spacing_m,
                    const InpaintOptions& options) {
    const int rows = img.rows, cols = img.cols, n_labels = holes.n_labels;
    std::vector<double> sq(n_labels, 0.0);
    std::vector<int> runs(n_labels, 0);
    const auto R = [&](int r, int c) { return static_cast<double>(img.radius.at<float>(r, c)); };
    const auto is_known = [&](int r, int c) {
        return r >= 0 && r < rows && img.known.at<std::uint8_t>(r, c);
    };
    constexpr int kSlopeRows = 4;
    for (int c = 0; c < cols; ++c)
        for (int r = 0; r < rows;) {
            if (!holes.target.at<std::uint8_t>(r, c)) {
                ++r;
                continue;
            }
            const int below = r - 1;  // last measured row below the run
            while (r < rows && holes.target.at<std::uint8_t>(r, c)) ++r;
            const int above = r;  // first measured row above it
            if (!is_known(below, c) || !is_known(above, c)) continue;
            int kb = 1, ka = 1;
            while (kb < kSlopeRows && is_known(below - kb, c)) ++kb;
            while (ka < kSlopeRows && is_known(above + ka, c)) ++ka;
            const double slope_b = kb > 1 ? (R(below, c) - R(below - kb + 1, c)) / (kb - 1) : 0;
            const double slope_a = ka > 1 ? (R(above + ka - 1, c) - R(above, c)) / (ka - 1) : 0;
            const double e = (R(above, c) - R(below, c)) -
                             0.5 * (slope_b + slope_a) * static_cast<double>(above - below);
            const int root = holes.labels.at<int>(below + 1, c);
            sq[root] += e * e;
            ++runs[root];
        }
    int steps = 0;
    for (int l = 1; l < n_labels; ++l) {
        if (!holes.fill[l] || runs[l] == 0) continue;
        if (std::sqrt(sq[l] / runs[l]) > options.max_step_rms * spacing_m) {
            holes.fill[l] = 0;
            ++steps;
        }
    }
    holes.update_target();
    return steps;
}

/// The radius map's biharmonic fill of the target pixels [M], harmonic on the steep components
/// (`px` the map's pixel in metres; `pad` the columns `r_wide` is padded with each side).
/// Reports biharmonic, harmonic_components and harmonic into `info`.
void steep_aware_biharmonic(cv::Mat& r_wide, const cv::Rect& crop, const HoleComponents& holes,
                            double px, int pad, const InpaintOptions& options, Report& info) {
    const cv::Mat& target = holes.target;
    const cv::Mat& labels = holes.labels;
    const int rows = target.rows, cols = target.cols, n_labels = holes.n_labels;
    // [M] Steep holes: where Telea's radius changes faster than the height (mean |dr/dh|
    // over the component above max_biharmonic_slope), the unseen surface is closer to
    // horizontal than vertical, the underside of an overhang whose rims are creases (the
    // edge of the chest above, the base below): continuing the rims' slopes (biharmonic)
    // rounds the creases into bulges below the overhang; the harmonic fill continues the
    // values only.
    std::vector<double> slope(n_labels, 0.0);
    std::vector<int> count(n_labels, 0);
    const cv::Mat centre = r_wide(crop);
    for (int r = 1; r + 1 < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            if (!target.at<std::uint8_t>(r, c)) continue;
            const int l = labels.at<int>(r, c);
            slope[l] +=
                std::abs(centre.at<float>(r + 1, c) - centre.at<float>(r - 1, c)) / (2 * px);
            ++count[l];
        }
    const auto is_steep = [&](int l) {
        return count[l] && slope[l] / count[l] > options.max_biharmonic_slope;
    };
    cv::Mat steep(rows, cols, CV_8U, cv::Scalar(0));
    int n_steep = 0;
    for (int l = 1; l < n_labels; ++l)
        if (is_steep(l)) ++n_steep;
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            const int l = labels.at<int>(r, c);
            if (target.at<std::uint8_t>(r, c) && l > 0 && is_steep(l))
                steep.at<std::uint8_t>(r, c) = 255;
        }
    cv::Mat smooth = target - steep;
    info["biharmonic"] = biharmonic(r_wide, wrap_pad(smooth, pad));
    info["harmonic_components"] = n_steep;
    if (n_steep) info["harmonic"] = biharmonic(r_wide, wrap_pad(steep, pad), true);
}

/// §12.2-12.3: inpaints the radius (Telea, then the steep-aware biharmonic and the 3x3 median
/// inside the target) and the colour (Telea, then Criminisi's exemplars on the target) of the
/// cylinder image in place, on wrap-padded copies. Every unknown pixel is inpainted so that
/// none acts as a known zero; only the target ones are used. Reports colour and the
/// biharmonic figures into `info`.
void inpaint_cylinder(CylinderImage& img, const HoleComponents& holes,
                      const InpaintOptions& options, Report& info) {
    const int rows = img.rows, cols = img.cols;
    const int pad = std::max(1, static_cast<int>(std::ceil(options.wrap * cols)));
    cv::Mat unknown = 255 - img.known;
    img.radius.setTo(0.0f, unknown);
    cv::Mat r_wide = wrap_pad(img.radius, pad), c_wide = wrap_pad(img.color, pad);
    const cv::Mat u_wide = wrap_pad(unknown, pad);
    const cv::Rect crop(std::min(pad, cols), 0, cols, rows);
    // The colour and the radius are independent chains (OpenCV's Telea is sequential): side by
    // side, each reporting into its own object.
    Report colour_info, radius_info = Report::object();
    const auto colour_chain = [&] {
        telea(c_wide, u_wide, options.telea_radius);
        // Exemplars for the target pixels of the centre copy only (the padding's copies of them
        // are cropped away); source patches anywhere, across the seam too.
        cv::Mat t_centre = cv::Mat::zeros(c_wide.size(), CV_8U);
        holes.target.copyTo(t_centre(crop));
        colour_info = inpaint_colour(c_wide, t_centre, wrap_pad(img.known, pad), options);
    };
    const auto radius_chain = [&] {
        telea(r_wide, u_wide, options.telea_radius);
        if (options.biharmonic)
            steep_aware_biharmonic(r_wide, crop, holes, img.px, pad, options, radius_info);
        // §12.3: 3x3 median inside the filled region only.
        if (options.median) {
            cv::Mat med;
            cv::medianBlur(r_wide, med, 3);
            med(crop).copyTo(r_wide(crop), holes.target);
        }
    };
    tbb::parallel_invoke(radius_chain, colour_chain);
    info["colour"] = std::move(colour_info);
    info.update(radius_info);
    img.radius = r_wide(crop).clone();
    img.color = c_wide(crop).clone();
}

/// Back to 3D: the target pixels of the inpainted image, resampled at `options.step` spacings
/// by bilinear interpolation, each with the normal of the inpainted radius map and its
/// component as the loop.
Candidates lift_to_3d(const CylinderImage& img, const HoleComponents& holes, const BodyAxis& axis,
                      double spacing_m, const InpaintOptions& options) {
    const int rows = img.rows, cols = img.cols;
    const double px = img.px, dtheta = img.dtheta;
    const cv::Mat& radius = img.radius;
    const Eigen::Vector3d& up = axis.up;
    Candidates cand;
    const double step = options.step * spacing_m;
    const int n_h = std::max(1, static_cast<int>(std::lround(px / step)));
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            if (!holes.target.at<std::uint8_t>(r, c)) continue;
            const float r0 = radius.at<float>(r, c);
            const int n_t = std::max(1, static_cast<int>(std::lround(r0 * dtheta / step)));
            const int cl = (c + cols - 1) % cols, cr = (c + 1) % cols;
            const int rl = std::max(r - 1, 0), rh = std::min(r + 1, rows - 1);
            const double r_t = (radius.at<float>(r, cr) - radius.at<float>(r, cl)) / (2 * dtheta);
            const double r_h =
                (radius.at<float>(rh, c) - radius.at<float>(rl, c)) / (std::max(rh - rl, 1) * px);
            for (int a = 0; a < n_t; ++a)
                for (int b = 0; b < n_h; ++b) {
                    const double fc = c + (a + 0.5) / n_t - 0.5;
                    const double fr = r + (b + 0.5) / n_h - 0.5;
                    const double rr = bilinear(radius, fr, fc, true);
                    const double th = -M_PI + (fc + 0.5) * dtheta;
                    const double h = img.h_min + (fr + 0.5) * px;
                    const Eigen::Vector3d out = std::cos(th) * img.e1 + std::sin(th) * img.e2;
                    const Eigen::Vector3d tangent = out.cross(up);  // d(out)/d(theta) = -tangent
                    // P(theta, h) = origin + r out + h up.
                    const Eigen::Vector3d dp_dt = r_t * out - rr * tangent;
                    const Eigen::Vector3d dp_dh = r_h * out + up;
                    Eigen::Vector3d nn = dp_dt.cross(dp_dh).normalized();
                    if (nn.dot(out) < 0) nn = -nn;
                    cand.push(axis.origin + rr * out + h * up, nn, pixel_rgb(img.color, r, c),
                              static_cast<std::uint32_t>(holes.labels.at<int>(r, c)));
                }
        }
    return cand;
}

}  // namespace

FillResult fill_large_holes(const SurfacePoints& points,
                            const std::vector<Eigen::Vector3d>& normals, const BodyAxis& axis,
                            double spacing_m, const std::vector<SensorView>& sensors,
                            const InpaintOptions& options, double top_limit, Report* report,
                            const Progress& progress) {
    options.check();
    check_input(points, normals, spacing_m);
    Stopwatch watch;
    FillResult result;
    Report info;
    auto finish = [&]() {
        info["points_added"] = result.position.size();
        info["time_s"] = watch.seconds();
        if (report) (*report)["large_holes"] = info;
        return result;
    };
    if (points.size() < 10) return finish();
    CylinderImage img = unroll_on_cylinder(points, normals, axis, spacing_m, options);
    info["image"] = {img.cols, img.rows};
    const int top_row =
        std::isfinite(top_limit)
            ? std::clamp(static_cast<int>(std::floor((top_limit - img.h_min) / img.px)), -1,
                         img.rows - 1)
            : img.rows - 1;
    HoleComponents holes = find_hole_components(img, top_row, options, info);
    int filled = static_cast<int>(std::count(holes.fill.begin(), holes.fill.end(), 1));
    int steps = 0;
    if (filled > 0 && std::isfinite(options.max_step_rms)) {
        steps = apply_step_test(img, holes, spacing_m, options);
        filled -= steps;
    }
    info["skipped_step"] = steps;
    info["hole_components"] = filled;
    const int target_pixels = cv::countNonZero(holes.target);
    info["hole_pixels"] = target_pixels;
    if (target_pixels == 0) return finish();
    if (!report_progress(progress, 0.2)) throw AlgorithmError("cancelled");
    inpaint_cylinder(img, holes, options, info);
    if (!report_progress(progress, 0.6)) throw AlgorithmError("cancelled");
    Candidates cand = lift_to_3d(img, holes, axis, spacing_m, options);
    keep_candidates(cand, points, sensors, spacing_m, options, FillMechanism::kLargeHole, result,
                    info);
    if (!report_progress(progress, 1.0)) throw AlgorithmError("cancelled");
    return finish();
}

}  // namespace rgbd::holes
