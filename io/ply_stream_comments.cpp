// The rgbd: comment lines of a stream document <-> ViewInfo. See io/ply_stream.hpp.
#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <istream>
#include <limits>
#include <optional>
#include <ostream>
#include <sstream>
#include <string_view>

#include "io/internal/mesh_soup.hpp"
#include "io/internal/ply_format.hpp"
#include "io/ply_stream.hpp"
#include "toolkit/error.hpp"
namespace rgbd::io {

using namespace internal::ply;

std::vector<std::string> view_to_comments(const ViewInfo& view, DocumentKind kind) {
    std::vector<std::string> c;
    c.push_back("rgbd:stream 1");
    c.push_back(std::string("rgbd:kind ") + (kind == DocumentKind::kMesh ? "mesh" : "points"));
    c.push_back("rgbd:units m");
    if (view.id != -1) c.push_back("rgbd:view.id " + std::to_string(view.id));
    if (!view.sensor.empty()) c.push_back("rgbd:view.sensor " + one_line(view.sensor));
    if (view.time_ns) c.push_back("rgbd:view.time_ns " + std::to_string(*view.time_ns));
    if (view.frame_index) c.push_back("rgbd:view.frame_index " + std::to_string(*view.frame_index));
    c.push_back(std::string("rgbd:view.frame ") +
                (view.frame == ViewFrame::kWorld ? "world" : "sensor"));
    if (view.intrinsics) {
        const PinholeIntrinsics& k = *view.intrinsics;
        c.push_back("rgbd:camera.intrinsics " + std::to_string(k.width) + " " +
                    std::to_string(k.height) + " " + format_double(k.fx) + " " +
                    format_double(k.fy) + " " + format_double(k.cx) + " " + format_double(k.cy));
        if (k.distortion.model != "none" || !k.distortion.coeffs.empty()) {
            std::string d = "rgbd:camera.distortion " + one_line(k.distortion.model);
            for (double v : k.distortion.coeffs) d += " " + format_double(v);
            c.push_back(d);
        }
    }
    if (view.world_from_sensor)
        c.push_back("rgbd:pose.world_from_sensor" + pose_text(*view.world_from_sensor));
    if (view.grid_width != 0 || view.grid_height != 0)
        c.push_back("rgbd:grid " + std::to_string(view.grid_width) + " " +
                    std::to_string(view.grid_height));
    if (!view.source.empty()) c.push_back("rgbd:view.source " + one_line(view.source));
    for (const std::string& h : view.history) c.push_back("rgbd:history " + one_line(h));
    for (const std::string& e : view.extra_comments) c.push_back(one_line(e));
    return c;
}

ViewInfo view_from_comments(const std::vector<std::string>& comments) {
    ViewInfo view;
    std::optional<Distortion> distortion;
    for (const std::string& line : comments) {
        const std::string_view text = line;
        if (text.substr(0, 5) != "rgbd:") {
            view.extra_comments.push_back(line);
            continue;
        }
        const std::size_t space = text.find_first_of(" \t");
        const std::string_view key = text.substr(0, space);
        const std::string_view rest =
            space == std::string_view::npos ? std::string_view() : trim(text.substr(space + 1));
        // Single-string values keep inner spaces; only the one separator is removed.
        const std::string_view raw_rest =
            space == std::string_view::npos ? std::string_view() : text.substr(space + 1);
        const auto values = split(rest);
        const auto bad = [&](const std::string& why) -> InputError {
            return InputError("malformed comment '" + line.substr(0, 80) + "': " + why);
        };
        const auto number = [&](std::size_t i) {
            const auto v = parse_double(values[i]);
            if (!v || !std::isfinite(*v))
                throw bad("'" + std::string(values[i]) + "' is not a number");
            return *v;
        };
        const auto integer = [&](std::size_t i) {
            const auto v = parse_int<std::int64_t>(values[i]);
            if (!v) throw bad("'" + std::string(values[i]) + "' is not an integer");
            return *v;
        };
        const auto expect = [&](std::size_t n) {
            if (values.size() != n)
                throw bad("expected " + std::to_string(n) + " values, got " +
                          std::to_string(values.size()));
        };
        if (key == "rgbd:stream") {
            expect(1);
            if (integer(0) != 1)
                throw bad("unsupported stream version (this reader knows rgbd:stream 1)");
        } else if (key == "rgbd:kind") {
            expect(1);
            if (values[0] != "points" && values[0] != "mesh") throw bad("kind is points or mesh");
        } else if (key == "rgbd:units") {
            expect(1);
            if (values[0] != "m") throw bad("only metres (m) are supported");
        } else if (key == "rgbd:view.id") {
            expect(1);
            const auto id = integer(0);
            if (id < -1 || id > std::numeric_limits<int>::max()) throw bad("id out of range");
            view.id = static_cast<int>(id);
        } else if (key == "rgbd:view.sensor") {
            view.sensor = std::string(raw_rest);
        } else if (key == "rgbd:view.time_ns") {
            expect(1);
            view.time_ns = integer(0);
        } else if (key == "rgbd:view.frame_index") {
            expect(1);
            view.frame_index = integer(0);
        } else if (key == "rgbd:view.frame") {
            expect(1);
            if (values[0] == "sensor") {
                view.frame = ViewFrame::kSensor;
            } else if (values[0] == "world") {
                view.frame = ViewFrame::kWorld;
            } else {
                throw bad("frame is sensor or world");
            }
        } else if (key == "rgbd:camera.intrinsics") {
            expect(6);
            PinholeIntrinsics k;
            const auto w = integer(0), h = integer(1);
            if (w <= 0 || h <= 0 || w > 100000 || h > 100000) throw bad("bad image size");
            k.width = static_cast<int>(w);
            k.height = static_cast<int>(h);
            k.fx = number(2);
            k.fy = number(3);
            k.cx = number(4);
            k.cy = number(5);
            if (!(k.fx > 0 && k.fy > 0)) throw bad("focal lengths must be positive");
            if (view.intrinsics) k.distortion = view.intrinsics->distortion;
            view.intrinsics = k;
        } else if (key == "rgbd:camera.distortion") {
            if (values.empty()) throw bad("missing model");
            Distortion d;
            d.model = std::string(values[0]);
            for (std::size_t i = 1; i < values.size(); ++i) d.coeffs.push_back(number(i));
            try {
                d.check();
            } catch (const InputError& e) {
                throw bad(e.what());
            }
            distortion = d;
        } else if (key == "rgbd:pose.world_from_sensor") {
            expect(12);
            std::array<double, 12> m{};
            for (std::size_t i = 0; i < 12; ++i) m[i] = number(i);
            try {
                pose_from_3x4(m);  // validation only; keep the exact numbers below
            } catch (const InputError& e) {
                throw bad(e.what());
            }
            Pose pose = Pose::Identity();
            for (int r = 0; r < 3; ++r) {
                for (int col = 0; col < 3; ++col) pose.matrix()(r, col) = m[r * 4 + col];
                pose.matrix()(r, 3) = m[r * 4 + 3];
            }
            view.world_from_sensor = pose;
        } else if (key == "rgbd:grid") {
            expect(2);
            const auto w = integer(0), h = integer(1);
            if (w < 0 || h < 0 || w > 100000 || h > 100000) throw bad("bad grid size");
            view.grid_width = static_cast<int>(w);
            view.grid_height = static_cast<int>(h);
        } else if (key == "rgbd:view.source") {
            view.source = std::string(raw_rest);
        } else if (key == "rgbd:history") {
            view.history.emplace_back(raw_rest);
        } else {
            view.extra_comments.push_back(line);
        }
    }
    if (distortion) {
        if (!view.intrinsics)
            throw InputError("rgbd:camera.distortion without rgbd:camera.intrinsics");
        view.intrinsics->distortion = *distortion;
    }
    return view;
}

}  // namespace rgbd::io
