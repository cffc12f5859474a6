#include "validation/synth/scene.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "toolkit/error.hpp"
#include "toolkit/random.hpp"
#include "validation/synth/random.hpp"

namespace rgbd::synth {
namespace {

using Vec3 = Eigen::Vector3d;
constexpr double kDeg = std::numbers::pi / 180.0;
constexpr double kWallHeightM = 2.5;
constexpr double kWallGapM = 1.0;           // walls at ring radius + this
constexpr double kSensorClearanceM = 0.25;  // clutter and people keep this far from sensors
constexpr double kSubjectClearanceM = 0.3;  // clutter keeps this far from the subject's bbox
constexpr int kPlaceAttempts = 500;
constexpr Rgb kPlatterColor{38, 38, 42};  // the turntable platter (dark grey rubber)
constexpr Rgb kFloorColor{128, 127, 124};
constexpr Rgb kWallColor{214, 209, 198};
constexpr Rgb kPlinthColor{176, 170, 160};
constexpr Rgb kTrousers{52, 58, 82};
constexpr Rgb kSkin{206, 166, 136};
constexpr std::array<Rgb, 8> kPalette = {{{178, 62, 50},
                                          {58, 118, 182},
                                          {204, 172, 58},
                                          {78, 150, 82},
                                          {148, 88, 160},
                                          {222, 132, 56},
                                          {90, 170, 170},
                                          {120, 84, 60}}};

const char* kind_name(ElementKind k) {
    switch (k) {
        case ElementKind::kPlatter:
            return "platter";
        case ElementKind::kFloor:
            return "floor";
        case ElementKind::kPlinth:
            return "plinth";
        case ElementKind::kWall:
            return "wall";
        case ElementKind::kBox:
            return "box";
        case ElementKind::kCylinder:
            return "cylinder";
        case ElementKind::kPerson:
            return "person";
    }
    return "?";
}

nlohmann::json vec_json(const Vec3& v) { return {v.x(), v.y(), v.z()}; }

/// Appends the quad origin + s a + t b (s, t in [0, 1]) as a grid of cells no longer than
/// max_edge (the rasteriser drops a triangle with a vertex behind the near plane, so large faces
/// near a camera are cut into small ones).
void add_grid_quad(SceneSoup& soup, const Vec3& origin, const Vec3& a, const Vec3& b,
                   double max_edge) {
    const int na = std::max(1, static_cast<int>(std::ceil(a.norm() / max_edge)));
    const int nb = std::max(1, static_cast<int>(std::ceil(b.norm() / max_edge)));
    const int base = static_cast<int>(soup.vertices.size());
    for (int j = 0; j <= nb; ++j)
        for (int i = 0; i <= na; ++i)
            soup.vertices.push_back(origin + a * (double(i) / na) + b * (double(j) / nb));
    for (int j = 0; j < nb; ++j)
        for (int i = 0; i < na; ++i) {
            const int v00 = base + j * (na + 1) + i, v10 = v00 + 1, v01 = v00 + na + 1,
                      v11 = v01 + 1;
            soup.triangles.push_back({v00, v10, v11});
            soup.triangles.push_back({v00, v11, v01});
        }
}

/// A box standing at `bottom_centre`, size (sx along (cos yaw, sin yaw), sy across, sz up).
void add_box(SceneSoup& soup, const Vec3& bottom_centre, const Vec3& size, double yaw,
             double max_edge) {
    const Vec3 u(std::cos(yaw), std::sin(yaw), 0), v(-std::sin(yaw), std::cos(yaw), 0);
    const Vec3 a = size.x() * u, b = size.y() * v, w = size.z() * Vec3::UnitZ();
    const Vec3 c0 = bottom_centre - 0.5 * a - 0.5 * b;
    add_grid_quad(soup, c0, a, b, max_edge);      // bottom
    add_grid_quad(soup, c0 + w, a, b, max_edge);  // top
    add_grid_quad(soup, c0, a, w, max_edge);      // sides
    add_grid_quad(soup, c0 + b, a, w, max_edge);
    add_grid_quad(soup, c0, b, w, max_edge);
    add_grid_quad(soup, c0 + a, b, w, max_edge);
}

/// A vertical cylinder standing at `bottom_centre` (32 sides, capped).
void add_cylinder(SceneSoup& soup, const Vec3& bottom_centre, double radius, double height,
                  double max_edge) {
    constexpr int kSides = 32;
    const int rings = std::max(1, static_cast<int>(std::ceil(height / max_edge)));
    const int base = static_cast<int>(soup.vertices.size());
    for (int k = 0; k <= rings; ++k)
        for (int s = 0; s < kSides; ++s) {
            const double a = 2.0 * std::numbers::pi * s / kSides;
            soup.vertices.push_back(bottom_centre + Vec3(radius * std::cos(a), radius * std::sin(a),
                                                         height * k / rings));
        }
    const auto at = [&](int k, int s) { return base + k * kSides + s % kSides; };
    for (int k = 0; k < rings; ++k)
        for (int s = 0; s < kSides; ++s) {
            soup.triangles.push_back({at(k, s), at(k, s + 1), at(k + 1, s + 1)});
            soup.triangles.push_back({at(k, s), at(k + 1, s + 1), at(k + 1, s)});
        }
    const int bottom = static_cast<int>(soup.vertices.size());
    soup.vertices.push_back(bottom_centre);
    soup.vertices.push_back(bottom_centre + Vec3(0, 0, height));
    for (int s = 0; s < kSides; ++s) {
        soup.triangles.push_back({bottom, at(0, s + 1), at(0, s)});
        soup.triangles.push_back({bottom + 1, at(rings, s), at(rings, s + 1)});
    }
}

/// Horizontal distance from p to the rectangle [lo, hi] (0 inside).
double distance_to_rect(const Eigen::Vector2d& p, const Eigen::Vector2d& lo,
                        const Eigen::Vector2d& hi) {
    const Eigen::Vector2d d = (lo - p).cwiseMax(p - hi).cwiseMax(0.0);
    return d.norm();
}

/// A footprint already taken (clutter, people): centre and circumscribed radius.
struct Footprint {
    Eigen::Vector2d centre;
    double radius;
};

Rgb scaled(Rgb c, double f) {
    const auto s = [f](std::uint8_t v) {
        return static_cast<std::uint8_t>(std::clamp(std::lround(v * f), 0L, 255L));
    };
    return {s(c.r), s(c.g), s(c.b)};
}

/// Uniform in [-1, 1] for the cell of p at size `cell` (a fixed grain pattern).
double grain(const Vec3& p, double cell) {
    const auto q = [cell](double x) {
        return static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(x / cell)));
    };
    const std::uint64_t h =
        splitmix64(q(p.x()) * 0x9e3779b97f4a7c15ULL ^ splitmix64(q(p.y()) + 0x632be5ab) ^
                   splitmix64(q(p.z()) + 0x85157af5));
    return 2.0 * unit_interval(h) - 1.0;
}

}  // namespace

// ---------------------------------------------------------------- options

void SceneOptions::check() const {
    check_range("plinth_height_m", plinth_height_m, Range::closed(0, 10), "m");
    check_range("scene walls", walls, Range::closed(0, 4));
    check_range("scene clutter", clutter, Range::closed(0, 50));
    check_range("scene people", people, Range::closed(0, 20));
}

nlohmann::json SceneOptions::to_json() const {
    return {{"floor", floor},
            {"plinth_height_m", plinth_height_m},
            {"walls", walls},
            {"clutter", clutter},
            {"people", people}};
}

SceneOptions scene_preset(const std::string& name) {
    SceneOptions s;
    if (name == "bare") return s;
    if (name == "room") {
        s.floor = true;
        s.walls = 2;
        s.clutter = 4;
        s.people = 1;
        return s;
    }
    throw InputError("unknown scene '" + name + "' (expected bare or room)");
}

// ---------------------------------------------------------------- surroundings

const SceneElement* Surroundings::element_of(int triangle) const {
    if (object_triangles < 0 || triangle < object_triangles) return nullptr;
    const auto it =
        std::upper_bound(elements.begin(), elements.end(), triangle,
                         [](int t, const SceneElement& e) { return t < e.end_triangle; });
    return it != elements.end() && triangle >= it->first_triangle ? &*it : nullptr;
}

SegmentLabel Surroundings::label_of(int triangle) const {
    const SceneElement* e = element_of(triangle);
    return e ? e->label : SegmentLabel::kSubject;
}

nlohmann::json Surroundings::to_json() const {
    nlohmann::json list = nlohmann::json::array();
    for (const auto& e : elements) {
        nlohmann::json j = e.geometry;
        j["kind"] = kind_name(e.kind);
        j["label"] = static_cast<int>(e.label);
        j["rgb"] = {e.rgb.r, e.rgb.g, e.rgb.b};
        list.push_back(std::move(j));
    }
    nlohmann::json out = {
        {"labels",
         "gt/<sensor>/segment/: 0 no return, 1 subject, 2 support (floor, plinth, "
         "platter), 3 background (walls, clutter, people), 4 valid depth, no surface"},
        {"elements", list}};
    out["floor_z"] = std::isfinite(floor_z) ? nlohmann::json(floor_z) : nlohmann::json(nullptr);
    return out;
}

void add_platter(SceneSoup& soup, Surroundings& out, const Vec3& c, double r_max) {
    SceneElement e;
    e.kind = ElementKind::kPlatter;
    e.label = SegmentLabel::kSupport;
    e.rgb = kPlatterColor;
    e.first_triangle = static_cast<int>(soup.triangles.size());
    auto& v = soup.vertices;
    auto& t = soup.triangles;
    const double radius = 1.25 * r_max + 0.01, thickness = 0.02;
    constexpr int kSides = 96;
    const int base = static_cast<int>(v.size());
    v.push_back(c);                          // top centre
    v.push_back(c - Vec3(0, 0, thickness));  // bottom centre
    for (int k = 0; k < kSides; ++k) {
        const double a = 2.0 * std::numbers::pi * k / kSides;
        const Vec3 r(radius * std::cos(a), radius * std::sin(a), 0);
        v.push_back(c + r);
        v.push_back(c + r - Vec3(0, 0, thickness));
    }
    const auto top = [&](int k) { return base + 2 + 2 * (k % kSides); };
    for (int k = 0; k < kSides; ++k) {
        t.push_back({base, top(k), top(k + 1)});              // top face, normal +z
        t.push_back({base + 1, top(k + 1) + 1, top(k) + 1});  // bottom face
        t.push_back({top(k), top(k) + 1, top(k + 1) + 1});    // rim
        t.push_back({top(k), top(k + 1) + 1, top(k + 1)});
    }
    e.end_triangle = static_cast<int>(t.size());
    e.geometry = {{"top_centre", vec_json(c)}, {"radius_m", radius}, {"thickness_m", thickness}};
    out.elements.push_back(std::move(e));
}

void add_surroundings(SceneSoup& soup, Surroundings& out, const SceneOptions& o,
                      const SceneFrame& f) {
    o.check();
    if (!o.any()) return;
    const double lowest = f.subject_lo.z();
    const double floor_z = lowest - o.plinth_height_m;
    const double R = f.ring_radius_m;
    out.floor_z = floor_z;
    for (std::size_t i = 0; i < f.sensor_positions.size(); ++i)
        RGBD_CHECK(
            f.sensor_positions[i].z() > floor_z + 0.05,
            "the floor level (z = " + format_number(floor_z) + " m) must lie below the sensors");
    const auto begin = [&](ElementKind kind, SegmentLabel label, Rgb rgb, double base_z) {
        SceneElement e;
        e.kind = kind;
        e.label = label;
        e.rgb = rgb;
        e.base_z = base_z;
        e.first_triangle = static_cast<int>(soup.triangles.size());
        return e;
    };
    const auto finish = [&](SceneElement e, nlohmann::json geometry) {
        e.end_triangle = static_cast<int>(soup.triangles.size());
        e.geometry = std::move(geometry);
        out.elements.push_back(std::move(e));
    };
    const auto box_json = [](const Vec3& bottom_centre, const Vec3& size, double yaw) {
        return nlohmann::json{{"bottom_centre", vec_json(bottom_centre)},
                              {"size_m", vec_json(size)},
                              {"yaw_deg", yaw / kDeg}};
    };

    // The subject's footprint (and the plinth's): clutter keeps away from it.
    const Eigen::Vector2d centre_xy = 0.5 * (f.subject_lo + f.subject_hi).head<2>();
    Eigen::Vector2d half = 0.5 * (f.subject_hi - f.subject_lo).head<2>();
    if (o.plinth_height_m > 0) {
        const double side = 1.2 * 2.0 * half.maxCoeff();
        half = half.cwiseMax(0.5 * side);
        for (const auto& s : f.sensor_positions)
            RGBD_CHECK((s.head<2>() - centre_xy).cwiseAbs().maxCoeff() > 0.5 * side + 0.05 ||
                           s.z() > lowest + 0.05,
                       "the plinth (" + format_number(side) + " m wide) would enclose a sensor");
        SceneElement e = begin(ElementKind::kPlinth, SegmentLabel::kSupport, kPlinthColor, floor_z);
        const Vec3 bottom(centre_xy.x(), centre_xy.y(), floor_z),
            size(side, side, o.plinth_height_m);
        add_box(soup, bottom, size, 0.0, 0.1);
        finish(std::move(e), box_json(bottom, size, 0.0));
    }
    const Eigen::Vector2d keep_lo = centre_xy - half, keep_hi = centre_xy + half;

    const double side = std::max(8.0, 2.0 * R + 4.0);
    const double max_edge = std::max(0.25, side / 256.0);
    if (o.floor) {
        SceneElement e = begin(ElementKind::kFloor, SegmentLabel::kSupport, kFloorColor, floor_z);
        add_grid_quad(soup, Vec3(-0.5 * side, -0.5 * side, floor_z), Vec3(side, 0, 0),
                      Vec3(0, side, 0), max_edge);
        finish(std::move(e), {{"z", floor_z},
                              {"centre", vec_json(Vec3(0, 0, floor_z))},
                              {"side_m", side},
                              {"normal", vec_json(Vec3::UnitZ())}});
    }
    for (int k = 0; k < o.walls; ++k) {
        const double a = k * 90.0 * kDeg;
        const Vec3 d(std::cos(a), std::sin(a), 0), t(-std::sin(a), std::cos(a), 0);
        const double dist = R + kWallGapM;
        const Vec3 foot = dist * d + Vec3(0, 0, floor_z);
        SceneElement e = begin(ElementKind::kWall, SegmentLabel::kBackground, kWallColor, floor_z);
        add_grid_quad(soup, foot - 0.5 * side * t, side * t, kWallHeightM * Vec3::UnitZ(),
                      max_edge);
        finish(std::move(e), {{"azimuth_deg", k * 90.0},
                              {"distance_m", dist},
                              {"bottom_centre", vec_json(foot)},
                              {"normal", vec_json(-d)},
                              {"width_m", side},
                              {"height_m", kWallHeightM}});
    }

    // Clutter and people: rejection sampling, deterministic in the seed.
    const CounterRandom rng(derive_seed(f.seed, 0x5ce4e));
    std::vector<Footprint> taken;
    const auto free_at = [&](const Eigen::Vector2d& c, double radius) {
        for (const auto& s : f.sensor_positions)
            if ((s.head<2>() - c).norm() < radius + kSensorClearanceM) return false;
        for (const auto& t : taken)
            if ((t.centre - c).norm() < radius + t.radius + 0.05) return false;
        return true;
    };
    for (int i = 0; i < o.clutter; ++i) {
        bool placed = false;
        for (int attempt = 0; attempt < kPlaceAttempts && !placed; ++attempt) {
            const std::uint64_t n = static_cast<std::uint64_t>(i) * kPlaceAttempts + attempt;
            const double az = 2.0 * std::numbers::pi * rng.uniform(1, n);
            const double r = R * (0.6 + 0.7 * rng.uniform(2, n));
            const Eigen::Vector2d c(r * std::cos(az), r * std::sin(az));
            const bool box = rng.uniform(3, n) < 0.5;
            const Vec3 size(0.1 + 0.4 * rng.uniform(4, n), 0.1 + 0.4 * rng.uniform(5, n),
                            0.1 + 0.4 * rng.uniform(6, n));
            const double radius = box ? 0.5 * size.head<2>().norm() : 0.5 * size.x();
            if (distance_to_rect(c, keep_lo, keep_hi) < radius + kSubjectClearanceM ||
                !free_at(c, radius))
                continue;
            const Rgb rgb = kPalette[static_cast<std::size_t>(rng.uniform(7, n) * kPalette.size())];
            const double yaw = 2.0 * std::numbers::pi * rng.uniform(8, n);
            const Vec3 bottom(c.x(), c.y(), floor_z);
            SceneElement e = begin(box ? ElementKind::kBox : ElementKind::kCylinder,
                                   SegmentLabel::kBackground, rgb, floor_z);
            if (box) {
                add_box(soup, bottom, size, yaw, 0.1);
                finish(std::move(e), box_json(bottom, size, yaw));
            } else {
                add_cylinder(soup, bottom, 0.5 * size.x(), size.z(), 0.1);
                finish(std::move(e), {{"bottom_centre", vec_json(bottom)},
                                      {"radius_m", 0.5 * size.x()},
                                      {"height_m", size.z()}});
            }
            taken.push_back({c, radius});
            placed = true;
        }
        RGBD_CHECK(placed, "no free place for clutter item " + std::to_string(i + 1) + " of " +
                               std::to_string(o.clutter) + " (fewer, or a larger ring)");
    }
    const Vec3 person(0.45, 0.3, 1.7);
    double r_lo = 1.2 * R, r_hi = 1.6 * R;
    if (o.walls > 0) {  // stay in front of the walls
        r_hi = std::min(r_hi, R + kWallGapM - 0.5 * person.head<2>().norm());
        r_lo = std::min(r_lo, r_hi);
    }
    for (int i = 0; i < o.people; ++i) {
        bool placed = false;
        for (int attempt = 0; attempt < kPlaceAttempts && !placed; ++attempt) {
            const std::uint64_t n = static_cast<std::uint64_t>(i) * kPlaceAttempts + attempt;
            const double az = 2.0 * std::numbers::pi * rng.uniform(11, n);
            const double r = r_lo + (r_hi - r_lo) * rng.uniform(12, n);
            const Eigen::Vector2d c(r * std::cos(az), r * std::sin(az));
            const double radius = 0.5 * person.head<2>().norm();
            if (!free_at(c, radius)) continue;
            const Rgb shirt =
                kPalette[static_cast<std::size_t>(rng.uniform(13, n) * kPalette.size())];
            const double yaw = az + std::numbers::pi / 2;  // the wide side faces the axis
            const Vec3 bottom(c.x(), c.y(), floor_z);
            SceneElement e = begin(ElementKind::kPerson, SegmentLabel::kBackground, shirt, floor_z);
            add_box(soup, bottom, person, yaw, 0.1);
            finish(std::move(e), box_json(bottom, person, yaw));
            taken.push_back({c, radius});
            placed = true;
        }
        RGBD_CHECK(placed, "no free place for person " + std::to_string(i + 1) + " of " +
                               std::to_string(o.people));
    }
}

// ---------------------------------------------------------------- colour and labels

Rgb element_color(const SceneElement& e, const Vec3& p, const Vec3& normal) {
    if (e.kind == ElementKind::kPlatter) return e.rgb;
    static const Vec3 light = Vec3(0.4, 0.3, 1.0).normalized();
    double f = 0.72 + 0.28 * std::abs(normal.dot(light));
    Rgb base = e.rgb;
    switch (e.kind) {
        case ElementKind::kFloor: {
            const long long cell = static_cast<long long>(std::floor(p.x() / 0.5)) +
                                   static_cast<long long>(std::floor(p.y() / 0.5));
            f *= (cell & 1 ? 0.93 : 1.0) * (1.0 + 0.04 * grain(p, 0.02));
            break;
        }
        case ElementKind::kWall:
            f *= 1.0 + 0.02 * grain(p, 0.05);
            break;
        case ElementKind::kPerson: {
            const double h = p.z() - e.base_z;
            if (h < 0.8) base = kTrousers;
            if (h > 1.45) base = kSkin;
            break;
        }
        default:
            break;
    }
    return scaled(base, f);
}

cv::Mat segment_image(const cv::Mat& triangle, const cv::Mat& noisy_depth, const Surroundings& s) {
    RGBD_CHECK(triangle.type() == CV_32SC1 && noisy_depth.type() == CV_32FC1 &&
                   triangle.size() == noisy_depth.size(),
               "segment_image needs a triangle image and a depth image of the same size");
    cv::Mat out(triangle.size(), CV_8UC1);
    for (int r = 0; r < triangle.rows; ++r)
        for (int c = 0; c < triangle.cols; ++c) {
            const int t = triangle.at<int>(r, c);
            SegmentLabel label = SegmentLabel::kNoReturn;
            if (std::isfinite(noisy_depth.at<float>(r, c)))
                label = t < 0 ? SegmentLabel::kNoSurface : s.label_of(t);
            out.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(label);
        }
    return out;
}

}  // namespace rgbd::synth
