// The third-party headers that most translation units of rgbd-toolkit include, precompiled once
// per kind of translation unit (cmake/pch/PrecompiledHeaders.cmake). Parsing them is most of
// the compile time of a tool or a test (CGAL's Surface_mesh alone is ~850 headers); a
// precompiled copy halves a typical translation unit's time. Only headers from outside the
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
