#include "algorithms/calibration/charuco_board.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "algorithms/internal/foreign_errors.hpp"
#include "toolkit/error.hpp"

namespace rgbd::calibration {
namespace {

const std::map<std::string, int>& dictionaries() {
    static const std::map<std::string, int> names = {
        {"DICT_4X4_50", cv::aruco::DICT_4X4_50},
        {"DICT_4X4_100", cv::aruco::DICT_4X4_100},
        {"DICT_4X4_250", cv::aruco::DICT_4X4_250},
        {"DICT_4X4_1000", cv::aruco::DICT_4X4_1000},
        {"DICT_5X5_50", cv::aruco::DICT_5X5_50},
        {"DICT_5X5_100", cv::aruco::DICT_5X5_100},
        {"DICT_5X5_250", cv::aruco::DICT_5X5_250},
        {"DICT_5X5_1000", cv::aruco::DICT_5X5_1000},
        {"DICT_6X6_50", cv::aruco::DICT_6X6_50},
        {"DICT_6X6_100", cv::aruco::DICT_6X6_100},
        {"DICT_6X6_250", cv::aruco::DICT_6X6_250},
        {"DICT_6X6_1000", cv::aruco::DICT_6X6_1000},
        {"DICT_7X7_50", cv::aruco::DICT_7X7_50},
        {"DICT_7X7_100", cv::aruco::DICT_7X7_100},
        {"DICT_7X7_250", cv::aruco::DICT_7X7_250},
        {"DICT_7X7_1000", cv::aruco::DICT_7X7_1000},
        {"DICT_ARUCO_ORIGINAL", cv::aruco::DICT_ARUCO_ORIGINAL}};
    return names;
}

/// Markers in a dictionary (the number after the last '_', 1024 for the original).
int dictionary_size(const std::string& name) {
    if (name == "DICT_ARUCO_ORIGINAL") return 1024;
    return std::stoi(name.substr(name.rfind('_') + 1));
}

cv::Ptr<cv::aruco::CharucoBoard> make_board(const BoardSpec& b) {
    return cv::aruco::CharucoBoard::create(
        b.squares_x, b.squares_y, static_cast<float>(b.square_m), static_cast<float>(b.marker_m),
        cv::aruco::getPredefinedDictionary(dictionaries().at(b.dictionary)));
}

cv::Matx33d camera_matrix(const PinholeIntrinsics& k) {
    return {k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1};
}

std::vector<double> distortion_vector(const PinholeIntrinsics& k) {
    if (k.distortion.is_none()) return {};
    std::vector<double> d = k.distortion.coeffs;
    d.resize(5, 0.0);
    return d;
}

/// A pixel size for messages, one decimal ("5.6").
std::string formatted_px(double px) {
    char text[32];
    std::snprintf(text, sizeof text, "%.1f", px);
    return text;
}

Pose pose_from_rvec(const cv::Vec3d& rvec, const cv::Vec3d& tvec) {
    cv::Matx33d r;
    cv::Rodrigues(rvec, r);
    Pose p = Pose::Identity();
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) p.linear()(i, j) = r(i, j);
        p.translation()[i] = tvec[i];
    }
    return p;
}

}  // namespace

void BoardSpec::check() const {
    check_range("board squares_x", squares_x, Range::closed(2, 40));
    check_range("board squares_y", squares_y, Range::closed(2, 40));
    check_range("board square", square_m, Range::closed(0.005, 2.0), "m");
    RGBD_CHECK(std::isfinite(marker_m) && marker_m > 0.2 * square_m && marker_m < square_m,
               "board marker must be smaller than the square and over a fifth of it");
    RGBD_CHECK(dictionaries().count(dictionary) == 1,
               "unknown ArUco dictionary '" + dictionary + "' (e.g. DICT_5X5_100)");
    RGBD_CHECK(dictionary_size(dictionary) >= squares_x * squares_y / 2,
               "dictionary " + dictionary + " has fewer markers than the board's " +
                   std::to_string(squares_x * squares_y / 2));
}

nlohmann::json BoardSpec::to_json() const {
    return {{"squares_x", squares_x},
            {"squares_y", squares_y},
            {"square_m", square_m},
            {"marker_m", marker_m},
            {"dictionary", dictionary}};
}

BoardSpec BoardSpec::from_json(const nlohmann::json& json) {
    RGBD_CHECK(json.is_object(), "board description must be a JSON object");
    BoardSpec b;
    // A square count must be a JSON integer: get<int>() converts 7.9 to 7, wraps 2^32 + 7
    // around to 7 and is undefined behaviour for 1e30 (issue 21).
    const auto count = [](const std::string& key, const nlohmann::json& value) {
        if (!value.is_number_integer()) throw InputError("key '" + key + "' must be an integer");
        const std::int64_t n = value.get<std::int64_t>();
        check_range("key '" + key + "'", n, Range::closed(2, 40));
        return static_cast<int>(n);
    };
    for (const auto& [key, value] : json.items()) {
        try {
            if (key == "squares_x")
                b.squares_x = count(key, value);
            else if (key == "squares_y")
                b.squares_y = count(key, value);
            else if (key == "square_m")
                b.square_m = value.get<double>();
            else if (key == "marker_m")
                b.marker_m = value.get<double>();
            else if (key == "dictionary")
                b.dictionary = value.get<std::string>();
            else
                throw InputError("unknown key '" + key + "'");
        } catch (const nlohmann::json::exception&) {
            throw InputError("key '" + key + "' has the wrong type");
        }
    }
    b.check();
    return b;
}

Eigen::Vector3d BoardSpec::corner(int id) const {
    const int nx = squares_x - 1;
    return {(id % nx + 1) * square_m, (id / nx + 1) * square_m, 0.0};
}

cv::Mat board_image(const BoardSpec& board, double pixels_per_m) {
    board.check();
    RGBD_CHECK(std::isfinite(pixels_per_m) && pixels_per_m > 0, "pixels per metre must be > 0");
    const double w = board.width_m() * pixels_per_m, h = board.height_m() * pixels_per_m;
    RGBD_CHECK(w >= 10 && h >= 10 && w <= 20000 && h <= 20000,
               "board image must be 10..20000 pixels a side");
    // OpenCV draws a marker of b x b bits plus a one-bit border into at least b + 2 pixels,
    // and its pixel size comes out of a few truncations of marker_m * pixels_per_m: ask for
    // two pixels more (a 6 x 32 board drawn 240 pixels high has 5.6-pixel markers, issue 39).
    const std::string name = std::to_string(board.squares_x) + " x " +
                             std::to_string(board.squares_y) + " board of " +
                             format_number(board.square_m) + " m squares";
    const int bits =
        cv::aruco::getPredefinedDictionary(dictionaries().at(board.dictionary))->markerSize;
    const double marker_px = board.marker_m * pixels_per_m;
    if (!(marker_px >= bits + 4))
        throw InputError("the " + name + ": markers of " + formatted_px(marker_px) +
                         " pixels are too small to draw at " + format_number(pixels_per_m) +
                         " pixels per metre (" + board.dictionary + " needs " +
                         std::to_string(bits + 4) + ")");
    return internal::with_foreign_errors("image of the " + name, [&] {
        cv::Mat image;
        make_board(board)->draw(
            cv::Size(static_cast<int>(std::lround(w)), static_cast<int>(std::lround(h))), image, 0,
            1);
        return image;
    });
}

void DetectionOptions::check() const {
    RGBD_CHECK(min_corners >= 4, "detection: min_corners must be >= 4");
    RGBD_CHECK(std::isfinite(max_rms_px) && max_rms_px > 0, "detection: max_rms_px must be > 0");
    check_range("detection: min_spread", min_spread, Range::closed(0, 1));
}

namespace {

/// detect_board after its checks; may throw OpenCV's exceptions.
DetectionOutcome detect_checked(const cv::Mat& image, const PinholeIntrinsics& intrinsics,
                                const BoardSpec& board, const DetectionOptions& options) {
    cv::Mat grey;
    if (image.channels() == 3)
        cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
    else
        grey = image;
    const auto cv_board = make_board(board);
    DetectionOutcome out;
    std::vector<int> marker_ids;
    std::vector<std::vector<cv::Point2f>> marker_corners, rejected;
    auto params = cv::aruco::DetectorParameters::create();
    params->cornerRefinementMethod = cv::aruco::CORNER_REFINE_NONE;  // ChArUco refines corners
    cv::aruco::detectMarkers(grey, cv_board->dictionary, marker_corners, marker_ids, params,
                             rejected);
    // Keep only the board's markers (ids beyond it belong to another board or are false).
    const int board_markers = static_cast<int>(cv_board->ids.size());
    std::vector<int> ids;
    std::vector<std::vector<cv::Point2f>> corners;
    for (std::size_t i = 0; i < marker_ids.size(); ++i)
        if (marker_ids[i] >= 0 && marker_ids[i] < board_markers) {
            ids.push_back(marker_ids[i]);
            corners.push_back(marker_corners[i]);
        }
    out.markers = static_cast<int>(ids.size());
    if (ids.empty()) return out;
    const cv::Matx33d k = camera_matrix(intrinsics);
    const std::vector<double> dist = distortion_vector(intrinsics);
    std::vector<cv::Point2f> cc;
    std::vector<int> cid;
    cv::aruco::interpolateCornersCharuco(corners, ids, grey, cv_board, cc, cid, k, dist, 2);
    out.corners = static_cast<int>(cid.size());
    if (out.corners < options.min_corners) {
        out.rejected = std::to_string(out.corners) + " corners (< " +
                       std::to_string(options.min_corners) + ")";
        return out;
    }
    // Spread: the corners must not sit in a tiny patch (the pose would be poorly determined).
    Eigen::Vector2d lo(1e9, 1e9), hi(-1e9, -1e9);
    for (int id : cid) {
        const Eigen::Vector2d p = board.corner(id).head<2>();
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
    }
    const double diagonal = std::hypot(board.width_m(), board.height_m());
    if ((hi - lo).norm() < options.min_spread * diagonal) {
        out.rejected = "corners cover too little of the board";
        return out;
    }
    cv::Vec3d rvec, tvec;
    if (!cv::aruco::estimatePoseCharucoBoard(cc, cid, cv_board, k, dist, rvec, tvec, false)) {
        out.rejected = "no board pose";
        return out;
    }
    std::vector<cv::Point3f> object;
    for (int id : cid) object.push_back(cv_board->chessboardCorners[id]);
    std::vector<cv::Point2f> projected;
    cv::projectPoints(object, rvec, tvec, k, dist, projected);
    double sum = 0;
    for (std::size_t i = 0; i < cc.size(); ++i) {
        const cv::Point2f d = projected[i] - cc[i];
        sum += d.dot(d);
    }
    const double rms = std::sqrt(sum / static_cast<double>(cc.size()));
    if (!(rms <= options.max_rms_px)) {
        char buf[96];
        std::snprintf(buf, sizeof buf, "reprojection RMS %.2f px (> %.2f)", rms,
                      options.max_rms_px);
        out.rejected = buf;
        return out;
    }
    BoardObservation obs;
    obs.ids = cid;
    for (const auto& p : cc) obs.pixels.emplace_back(p.x, p.y);
    obs.camera_from_board = pose_from_rvec(rvec, tvec);
    obs.rms_px = rms;
    obs.markers = out.markers;
    out.observation = std::move(obs);
    return out;
}

}  // namespace

DetectionOutcome detect_board(const cv::Mat& image, const PinholeIntrinsics& intrinsics,
                              const BoardSpec& board, const DetectionOptions& options) {
    board.check();
    options.check();
    RGBD_CHECK(!image.empty() && (image.type() == CV_8UC3 || image.type() == CV_8UC1),
               "board detection needs an 8-bit colour or grey image");
    return internal::with_foreign_errors(
        "detection of the " + std::to_string(board.squares_x) + " x " +
            std::to_string(board.squares_y) + " board in a " + std::to_string(image.cols) + " x " +
            std::to_string(image.rows) + " image",
        [&] { return detect_checked(image, intrinsics, board, options); });
}

PlaneCheck check_board_plane(const cv::Mat& depth_m, const PinholeIntrinsics& intrinsics,
                             const BoardSpec& board, const Pose& depth_from_board, double gate_m) {
    RGBD_CHECK(depth_m.type() == CV_32FC1, "board plane check needs a CV_32FC1 depth image");
    RGBD_CHECK(std::isfinite(gate_m) && gate_m > 0, "plane gate must be > 0 m");
    const Pose board_from_depth = depth_from_board.inverse();
    const double margin = 0.5 * board.square_m;
    const Eigen::Vector3d origin = depth_from_board.translation();
    const Eigen::Vector3d normal = depth_from_board.linear().col(2);
    std::vector<double> signed_mm;
    for (int r = 0; r < depth_m.rows; ++r) {
        const float* row = depth_m.ptr<float>(r);
        for (int c = 0; c < depth_m.cols; ++c) {
            const double z = row[c];
            if (!std::isfinite(z) || z <= 0) continue;
            // Where the pixel's ray meets the board plane: the pixels of the board are those
            // whose ray meets it inside the outline (shrunk by the margin).
            const Eigen::Vector3d ray = intrinsics.unproject(c, r, 1.0);  // z = 1
            const double denom = normal.dot(ray);
            if (std::abs(denom) < 1e-9) continue;
            const double t = normal.dot(origin) / denom;  // depth (z) of the plane on this ray
            if (t <= 0) continue;
            const Eigen::Vector3d b = board_from_depth * (t * ray);
            if (b.x() < margin || b.y() < margin || b.x() > board.width_m() - margin ||
                b.y() > board.height_m() - margin)
                continue;
            // Distance of the measured point to the plane, positive behind it.
            const double behind = (z - t) * std::abs(denom);
            if (std::abs(behind) > gate_m) continue;
            signed_mm.push_back(1e3 * behind);
        }
    }
    PlaneCheck out;
    out.pixels = static_cast<int>(signed_mm.size());
    if (signed_mm.empty()) return out;
    auto mid = signed_mm.begin() + signed_mm.size() / 2;
    std::nth_element(signed_mm.begin(), mid, signed_mm.end());
    out.median_mm = *mid;
    double sum = 0;
    for (double v : signed_mm) sum += (v - out.median_mm) * (v - out.median_mm);
    out.rms_mm = std::sqrt(sum / static_cast<double>(signed_mm.size()));
    return out;
}

}  // namespace rgbd::calibration
