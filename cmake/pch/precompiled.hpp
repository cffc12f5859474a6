// The third-party headers that most translation units of rgbd-toolkit include, precompiled once
// per kind of translation unit (cmake/pch/PrecompiledHeaders.cmake). Parsing them is most of
// the compile time of a tool or a test (CGAL's Surface_mesh alone is ~850 headers); with a
// precompiled copy cli/rgbd_mesh.cpp compiles in 8.3 s instead of 17.6 s, the libraries and
// rgbd-mesh in 784 s instead of 887 s (validation/results/2026-12-02-build-time-and-fold-
// smoothing.md). Only headers from outside the
// project belong here: a project header force-included everywhere would hide missing includes.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
