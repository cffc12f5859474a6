// upsample_quality: error of super-resolved points against a synthetic capture's truth
// (validation of docs/algorithms.md §5). Reads a view stream (sensor frame) whose new points carry
// prop::kSynthetic, brings every view into the world with the TRUE pose (gt/world_from_depth
// .json), and prints one JSON line: point ratio, RMS distance to gt/mesh.ply of original and
// new points, share of new points farther than 3 sigma_z(z) = 3 * 0.0015 (z/1.5)^2 m, mean
// absolute RGB error of new points against the procedural texture at the nearest true-surface
// point, and the same for nearest-neighbour colour copying (colour of the nearest original
// point of the view). With --peer cgal it first replaces the new points by those of CGAL
// edge_aware_upsample_point_set run on the original points (colours by projection into the
// view's colour image), so both are measured by the same code.
//
// Two helper modes for the real-frame part of run.sh:
//   --render-face STREAM.ply OUT.png [--view N]: side-by-side picture of one upsampled view of
//     a person (left: original points, right: original + new), splatted into a zoomed virtual
//     camera around the head (the top of the cloud; camera frame, y down);
//   --pcl-grabber DIR OUT: converts PCL OpenNI grabber frames (*_depth.tiff, *_rgb.tiff, xml
//     intrinsics) to an Open3D/Redwood folder (depth/ color/ intrinsic.json) rgbd-cloud reads.
//
// usage: upsample_quality CAPTURE STREAM.ply [--peer cgal] [--views N] [--factor F]
//                         [--threads N (default 1: timings are for one core)]
#include <CGAL/AABB_face_graph_triangle_primitive.h>
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/Orthogonal_k_neighbor_search.h>
#include <CGAL/Search_traits_3.h>
#include <CGAL/edge_aware_upsample_point_set.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <regex>

#include "algorithms/normals/estimate_normals.hpp"
#include "algorithms/sampling/robust_spacing.hpp"
#include "io/capture_folder.hpp"
#include "io/mesh_io.hpp"
#include "io/ply_stream.hpp"
#include "toolkit/error.hpp"
#include "toolkit/order_statistics.hpp"
#include "validation/synth/texture.hpp"

using namespace rgbd;
using Primitive = CGAL::AABB_face_graph_triangle_primitive<Mesh>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;
using SearchTraits = CGAL::Search_traits_3<Kernel>;
using Knn = CGAL::Orthogonal_k_neighbor_search<SearchTraits>;

namespace {

double sigma_z(double z) { return 0.0015 * (z / 1.5) * (z / 1.5); }

double rgb_error(Rgb a, Rgb b) {
    return (std::abs(a.r - b.r) + std::abs(a.g - b.g) + std::abs(a.b - b.b)) / 3.0;
}

/// CGAL edge-aware upsampling of the original points of `cloud` to `factor` x points; the new
/// points replace the synthetic ones, coloured from the colour image by projection.
double run_cgal(PointCloud& cloud, const RgbdFrame& frame, double factor) {
    const auto t0 = std::chrono::steady_clock::now();
    const std::size_t n = cloud.size();
    std::vector<std::pair<Point_3, Vector_3>> pts;
    PointCloud base;
    base.view = cloud.view;
    for (std::size_t i = 0; i < n; ++i) base.points.insert(cloud.points.point(PointSet::Index(i)));
    normals::NormalOptions nopt;
    normals::estimate_normals(base, nopt);
    for (auto idx : base.points) pts.emplace_back(base.points.point(idx), base.points.normal(idx));
    const double spacing = sampling::robust_spacing(base.points, 10000);
    CGAL::edge_aware_upsample_point_set<CGAL::Parallel_if_available_tag>(
        pts, std::back_inserter(pts),
        CGAL::parameters::point_map(
            CGAL::First_of_pair_property_map<std::pair<Point_3, Vector_3>>())
            .normal_map(CGAL::Second_of_pair_property_map<std::pair<Point_3, Vector_3>>())
            .sharpness_angle(25)
            .edge_sensitivity(0)
            .neighbor_radius(3 * spacing)
            .number_of_output_points(static_cast<std::size_t>(factor * n)));
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    auto flag = cloud.add_flag(prop::kSynthetic);
    auto colors = cloud.add_colors();
    cloud.points.resize(n);
    const std::size_t added = pts.size() > n ? pts.size() - n : 0;
    cloud.points.resize(n + added);
    for (std::size_t k = 0; k < added; ++k) {
        const PointSet::Index idx(n + k);
        const Point_3& p = pts[n + k].first;
        cloud.points.point(idx) = p;
        flag[idx] = 1;
        const Eigen::Vector2d q =
            frame.color_intrinsics.project(frame.color_from_depth * to_eigen(p));
        Rgb c{128, 128, 128};
        if (frame.color_intrinsics.contains(q)) {
            const cv::Vec3b b =
                frame.color.at<cv::Vec3b>(int(std::lround(q.y())), int(std::lround(q.x())));
            c = {b[2], b[1], b[0]};
        }
        colors.set(idx, c);
    }
    return seconds;
}

double quantile(std::vector<double> v, double q) {
    if (v.empty()) return 0.0;
    return rank_quantile(v, q);
}

/// Splats points (sensor frame) into a size x size image of a virtual pinhole camera looking
/// at `centre` with `width_m` across, nearest point per pixel.
cv::Mat splat(const std::vector<std::pair<Eigen::Vector3d, Rgb>>& points,
              const Eigen::Vector3d& centre, double width_m, int size) {
    cv::Mat image(size, size, CV_8UC3, cv::Scalar(0, 0, 0));
    cv::Mat zbuf(size, size, CV_64F, cv::Scalar(1e9));
    const double f = size * centre.z() / width_m;
    const double cu = centre.x() / centre.z(), cv_ = centre.y() / centre.z();
    for (const auto& [p, c] : points) {
        if (!(p.z() > 0.0)) continue;
        const int u = static_cast<int>(std::lround(f * (p.x() / p.z() - cu) + 0.5 * size));
        const int v = static_cast<int>(std::lround(f * (p.y() / p.z() - cv_) + 0.5 * size));
        if (u < 0 || v < 0 || u >= size || v >= size || p.z() >= zbuf.at<double>(v, u)) continue;
        zbuf.at<double>(v, u) = p.z();
        image.at<cv::Vec3b>(v, u) = cv::Vec3b(c.b, c.g, c.r);
    }
    return image;
}

/// --render-face: the original and the super-resolved points of one view, side by side.
int render_face(const std::string& stream, const std::string& out_png, int view_number) {
    std::ifstream in(stream, std::ios::binary);
    io::PlyStreamReader reader(in, stream);
    io::Document doc;
    for (int k = 0; k <= view_number; ++k)
        if (!reader.next(doc)) throw InputError(stream + ": fewer views than --view");
    const PointCloud& cloud = doc.cloud;
    const auto syn = cloud.flag(prop::kSynthetic);
    const auto colors = cloud.colors();
    std::vector<std::pair<Eigen::Vector3d, Rgb>> orig, all;
    std::vector<double> ys;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
        const PointSet::Index idx(i);
        const Eigen::Vector3d p = to_eigen(cloud.points.point(idx));
        all.emplace_back(p, colors.get(idx));
        if (syn && (*syn)[idx]) continue;
        orig.emplace_back(p, colors.get(idx));
        ys.push_back(p.y());
    }
    // Head: top of the cloud (0.2% quantile of y, y down); centre 11 cm below, median x, z.
    const double y_top = quantile(ys, 0.002);
    std::vector<double> xs, zs;
    for (const auto& [p, c] : orig)
        if (p.y() < y_top + 0.15) {
            xs.push_back(p.x());
            zs.push_back(p.z());
        }
    const Eigen::Vector3d centre(quantile(xs, 0.5), y_top + 0.11, quantile(zs, 0.5));
    const int size = 480;
    cv::Mat left = splat(orig, centre, 0.26, size), right = splat(all, centre, 0.26, size);
    auto label = [](cv::Mat& m, const std::string& text) {
        cv::putText(m, text, {8, 22}, cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(255, 255, 255), 1,
                    cv::LINE_AA);
    };
    label(left, "original: " + std::to_string(orig.size()) + " points");
    label(right, "upsampled: " + std::to_string(all.size()) + " points");
    cv::Mat both;
    cv::hconcat(left, right, both);
    io::write_image_atomic(out_png, both);
    nlohmann::json r;
    r["png"] = out_png;
    r["view"] = cloud.view.id;
    r["original_points"] = orig.size();
    r["all_points"] = all.size();
    r["head_centre_m"] = {centre.x(), centre.y(), centre.z()};
    std::cout << r.dump() << "\n";
    return 0;
}

/// --pcl-grabber: PCL OpenNI grabber frames -> Open3D/Redwood folder.
int convert_pcl_grabber(const std::string& dir, const std::string& out) {
    namespace fs = std::filesystem;
    std::vector<fs::path> depths;
    for (const auto& e : fs::directory_iterator(dir))
        if (e.path().string().ends_with("_depth.tiff")) depths.push_back(e.path());
    std::sort(depths.begin(), depths.end());
    if (depths.empty()) throw InputError(dir + ": no *_depth.tiff frames");
    // Intrinsics of the depth camera from the first xml (<depth><focal_length_x> ...).
    double fx = 525, fy = 525, cx = 319.5, cy = 239.5, z_factor = 0.001;
    for (const auto& e : fs::directory_iterator(dir))
        if (e.path().extension() == ".xml") {
            std::ifstream x(e.path());
            const std::string text((std::istreambuf_iterator<char>(x)), {});
            const auto depth_at = text.find("<depth>");
            auto get = [&](const std::string& key, double& v) {
                const std::regex re("<" + key + ">([^<]+)</" + key + ">");
                std::smatch m;
                const std::string part = text.substr(depth_at == std::string::npos ? 0 : depth_at);
                if (std::regex_search(part, m, re)) v = std::stod(m[1].str());
            };
            get("focal_length_x", fx);
            get("focal_length_y", fy);
            get("principal_point_x", cx);
            get("principal_point_y", cy);
            get("z_multiplication_factor", z_factor);
            break;
        }
    fs::create_directories(fs::path(out) / "depth");
    fs::create_directories(fs::path(out) / "color");
    int k = 0, width = 0, height = 0;
    for (const fs::path& d : depths) {
        const std::string stem = d.string().substr(0, d.string().size() - 11);
        cv::Mat depth = cv::imread(d.string(), cv::IMREAD_ANYDEPTH);
        cv::Mat color = cv::imread(stem + "_rgb.tiff", cv::IMREAD_COLOR);
        if (depth.empty() || color.empty()) throw IoError(stem + ": cannot read depth/rgb tiff");
        cv::Mat mm;  // 16-bit millimetres
        depth.convertTo(mm, CV_16U, z_factor * 1000.0);
        char name[32];
        std::snprintf(name, sizeof name, "%06d.png", k++);
        io::write_image_atomic(fs::path(out) / "depth" / name, mm);
        io::write_image_atomic(fs::path(out) / "color" / name, color);
        width = depth.cols;
        height = depth.rows;
    }
    nlohmann::json k_json;
    k_json["width"] = width;
    k_json["height"] = height;
    k_json["intrinsic_matrix"] = {fx, 0, 0, 0, fy, 0, cx, cy, 1};
    io::write_text_atomic(fs::path(out) / "intrinsic.json", k_json.dump(1) + "\n");
    std::cout << "{\"frames\": " << k << "}\n";
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 3) {
        std::cerr << "usage: upsample_quality CAPTURE STREAM.ply [--peer cgal] [--views N] "
                     "[--factor F] [--threads N]\n"
                     "       upsample_quality --render-face STREAM.ply OUT.png [--view N]\n"
                     "       upsample_quality --pcl-grabber DIR OUT\n";
        return 2;
    }
    try {
        if (std::string(argv[1]) == "--render-face" && argc >= 4)
            return render_face(
                argv[2], argv[3],
                argc >= 6 && std::string(argv[4]) == "--view" ? std::stoi(argv[5]) : 0);
        if (std::string(argv[1]) == "--pcl-grabber" && argc >= 4)
            return convert_pcl_grabber(argv[2], argv[3]);
    } catch (const std::exception& e) {
        std::cerr << "upsample_quality: error: " << e.what() << "\n";
        return 1;
    }
    const std::string cap_dir = argv[1], stream = argv[2];
    std::string peer;
    int max_views = 1000;
    double factor = 9.0;
    int threads = 1;
    for (int a = 3; a + 1 < argc; a += 2) {
        if (std::string(argv[a]) == "--peer") peer = argv[a + 1];
        if (std::string(argv[a]) == "--views") max_views = std::stoi(argv[a + 1]);
        if (std::string(argv[a]) == "--factor") factor = std::stod(argv[a + 1]);
        if (std::string(argv[a]) == "--threads") threads = std::stoi(argv[a + 1]);
    }
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                              static_cast<std::size_t>(std::max(1, threads)));
    try {
        const Mesh mesh = io::read_mesh(cap_dir + "/gt/mesh.ply");
        Tree tree(faces(mesh).first, faces(mesh).second, mesh);
        tree.accelerate_distance_queries();
        nlohmann::json poses, scene;
        std::ifstream(cap_dir + "/gt/world_from_depth.json") >> poses;
        std::ifstream(cap_dir + "/gt/scene.json") >> scene;
        synth::TextureOptions tex;
        const auto& t = scene["texture"];
        tex.hue_period_m = t.value("hue_period_m", tex.hue_period_m);
        tex.hue_offset_deg = t.value("hue_offset_deg", tex.hue_offset_deg);
        tex.saturation = t.value("saturation", tex.saturation);
        tex.value = t.value("value", tex.value);
        tex.checker_size_m = t.value("checker_size_m", tex.checker_size_m);
        tex.checker_dark = t.value("checker_dark", tex.checker_dark);
        const auto& oc = scene["mesh"]["object_centre"];
        const Eigen::Vector3d centre(oc[0], oc[1], oc[2]);
        const io::Capture capture = io::open_capture(cap_dir);

        std::ifstream in(stream, std::ios::binary);
        io::PlyStreamReader reader(in, stream);
        io::Document doc;
        std::size_t n_orig = 0, n_new = 0, far = 0;
        double se_orig = 0, se_new = 0, col_new = 0, col_nn = 0, peer_s = 0;
        int views = 0;
        while (reader.next(doc) && views < max_views) {
            PointCloud& cloud = doc.cloud;
            ++views;
            if (!peer.empty()) {
                const auto pos = capture.find_frame(cloud.view.sensor, *cloud.view.frame_index);
                const RgbdFrame frame = io::load_frame(capture, cloud.view.sensor, *pos);
                peer_s += run_cgal(cloud, frame, factor);
            }
            Eigen::Matrix4d m;
            const auto& pj = poses[cloud.view.sensor];
            for (int r = 0; r < 4; ++r)
                for (int c = 0; c < 4; ++c) m(r, c) = pj[r][c];
            Pose world_from_sensor(m);
            const auto syn = cloud.flag(prop::kSynthetic);
            const auto colors = cloud.colors();
            std::vector<Point_3> orig_pts;
            std::map<Point_3, Rgb> orig_rgb;
            for (std::size_t i = 0; i < cloud.size(); ++i) {
                const PointSet::Index idx(i);
                const Point_3 pw = to_point(world_from_sensor * to_eigen(cloud.points.point(idx)));
                const double d2 = CGAL::to_double(tree.squared_distance(pw));
                if (syn && (*syn)[idx]) continue;
                orig_pts.push_back(pw);
                orig_rgb[pw] = colors.get(idx);
                se_orig += d2;
                ++n_orig;
            }
            Knn::Tree knn(orig_pts.begin(), orig_pts.end());
            for (std::size_t i = 0; i < cloud.size(); ++i) {
                const PointSet::Index idx(i);
                if (!(syn && (*syn)[idx])) continue;
                const Eigen::Vector3d ps = to_eigen(cloud.points.point(idx));
                const Point_3 pw = to_point(world_from_sensor * ps);
                const Point_3 closest = tree.closest_point(pw);
                const double d2 = CGAL::squared_distance(pw, closest);
                se_new += d2;
                far += std::sqrt(d2) > 3.0 * sigma_z(ps.z());
                const Rgb truth = synth::texture_color(to_eigen(closest) - centre, tex);
                col_new += rgb_error(colors.get(idx), truth);
                Knn search(knn, pw, 1);
                col_nn += rgb_error(orig_rgb[search.begin()->first], truth);
                ++n_new;
            }
        }
        nlohmann::json r;
        r["views"] = views;
        r["ratio"] = double(n_orig + n_new) / double(n_orig);
        r["rms_orig_mm"] = 1e3 * std::sqrt(se_orig / std::max<std::size_t>(1, n_orig));
        r["rms_new_mm"] = 1e3 * std::sqrt(se_new / std::max<std::size_t>(1, n_new));
        r["far_3sigma_pct"] = 100.0 * far / std::max<std::size_t>(1, n_new);
        r["colour_err_new"] = col_new / std::max<std::size_t>(1, n_new);
        r["colour_err_nn_copy"] = col_nn / std::max<std::size_t>(1, n_new);
        if (!peer.empty()) r["peer_time_s"] = peer_s;
        r["threads"] = threads;
        std::cout << r.dump() << "\n";
        return 0;
    } catch (const std::exception& e) {
        std::cerr << "upsample_quality: error: " << e.what() << "\n";
        return 1;
    }
}
