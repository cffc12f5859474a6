// The team's real test data: ../shared/data beside the checkout (RGBD_SHARED_DATA, a CMake
// cache path). Tests that need it skip, naming what is missing, when it is absent.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

namespace rgbd::test {

/// A path inside the shared data folder.
inline std::filesystem::path shared_data(const std::string& relative) {
    return std::filesystem::path(RGBD_SHARED_DATA) / relative;
}

}  // namespace rgbd::test

/// Skips the current test, naming `path`, when `path` does not exist.
#define RGBD_SKIP_WITHOUT(path)         \
    if (!std::filesystem::exists(path)) \
    GTEST_SKIP() << "needs " << (path) << " (../shared/data is absent)"

/// Skips the current test when the shared data folder is absent.
#define RGBD_SKIP_WITHOUT_SHARED_DATA() RGBD_SKIP_WITHOUT(std::filesystem::path(RGBD_SHARED_DATA))
