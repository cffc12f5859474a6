// Scratch folders for tests that write files.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <string>

namespace rgbd::test {

/// <system temporary folder>/rgbd_<suite>_<pid>_<name>, emptied: removed when it existed, then
/// created again when `create` (otherwise left for the code under test to create). The
/// process id keeps parallel test runs apart; the test removes the folder when done.
inline std::filesystem::path fresh_temp_dir(const std::string& suite, const std::string& name,
                                            bool create = true) {
    const std::filesystem::path dir =
        std::filesystem::temp_directory_path() /
        ("rgbd_" + suite + "_" + std::to_string(::getpid()) + "_" + name);
    std::filesystem::remove_all(dir);
    if (create) std::filesystem::create_directories(dir);
    return dir;
}

}  // namespace rgbd::test
