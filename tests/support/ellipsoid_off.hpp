// A closed test mesh for the contract tests: a UV ellipsoid (poles on the y axis) written as
// OFF, optionally with a bump that scales its x and z radii; and the pipeline tests' ring capture
// of a bumpy one.
#pragma once

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>

#include "tests/support/tool_runner.hpp"

namespace rgbd::test {

/// Writes an nu x nv UV ellipsoid with radii (rx, ry, rz) to `path`: nu (nv - 1) + 2 vertices,
/// 2 nu (nv - 1) triangles, outward-facing. `bump(theta, phi)` multiplies the x and z radii.
inline void write_ellipsoid_off(const std::filesystem::path& path, int nu, int nv, double rx,
                                double ry, double rz,
                                const std::function<double(double, double)>& bump = {}) {
    std::ofstream off(path);
    off << "OFF\n" << (nu * (nv - 1) + 2) << " " << (2 * nu * (nv - 1)) << " 0\n";
    off << "0 " << ry << " 0\n";
    for (int j = 1; j < nv; ++j)
        for (int i = 0; i < nu; ++i) {
            const double th = M_PI * j / nv, ph = 2 * M_PI * i / nu;
            const double b = bump ? bump(th, ph) : 1.0;
            off << rx * b * std::sin(th) * std::cos(ph) << " " << ry * std::cos(th) << " "
                << rz * b * std::sin(th) * std::sin(ph) << "\n";
        }
    off << "0 " << -ry << " 0\n";
    const int south = nu * (nv - 1) + 1;
    const auto id = [&](int j, int i) { return 1 + (j - 1) * nu + (i % nu); };
    for (int i = 0; i < nu; ++i) off << "3 0 " << id(1, i + 1) << " " << id(1, i) << "\n";
    for (int j = 1; j < nv - 1; ++j)
        for (int i = 0; i < nu; ++i) {
            off << "3 " << id(j, i) << " " << id(j, i + 1) << " " << id(j + 1, i + 1) << "\n";
            off << "3 " << id(j, i) << " " << id(j + 1, i + 1) << " " << id(j + 1, i) << "\n";
        }
    for (int i = 0; i < nu; ++i)
        off << "3 " << south << " " << id(nv - 1, i) << " " << id(nv - 1, i + 1) << "\n";
}

/// The pipeline tests' capture: `dir`/blob.off, a 48 x 24 ellipsoid with radii (0.3, 0.5,
/// 0.25) m whose x and z radii carry a bump 1 + 0.08 sin(3 phi) sin(2 theta), rendered by
/// rgbd-synth into `dir`/cap as a 6-sensor Kinect v2 ring (colour 1920x1080 over depth 512x424,
/// object 0.5 m high, seed 3). Does nothing when `dir`/cap exists; a fatal test failure when
/// rgbd-synth fails.
inline void render_bumpy_ring(const std::filesystem::path& dir) {
    if (std::filesystem::exists(dir / "cap")) return;
    write_ellipsoid_off(dir / "blob.off", 48, 24, 0.3, 0.5, 0.25, [](double th, double ph) {
        return 1.0 + 0.08 * std::sin(3 * ph) * std::sin(2 * th);
    });
    const Outcome r =
        run_in(dir, "$BIN/rgbd-synth blob.off -o cap --sensors 6 --height-m 0.5 --seed 3 -q");
    ASSERT_EQ(r.code, 0) << r.err;
}

}  // namespace rgbd::test
