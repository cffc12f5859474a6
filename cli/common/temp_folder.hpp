// A scratch folder for a tool's intermediate files (the peers' inputs and outputs of rgbd-eval).
#pragma once

#include <unistd.h>

#include <filesystem>
#include <string>
#include <system_error>

namespace rgbd::cli {

/// A folder `prefix`-PID in the system's temporary directory, emptied when made and removed with
/// everything in it on destruction (errors on removal are ignored).
struct TempFolder {
    std::filesystem::path path;
    explicit TempFolder(const std::string& prefix)
        : path(std::filesystem::temp_directory_path() / (prefix + std::to_string(::getpid()))) {
        std::filesystem::remove_all(path);
        std::filesystem::create_directories(path);
    }
    ~TempFolder() {
        std::error_code ec;
        std::filesystem::remove_all(path, ec);
    }
    TempFolder(const TempFolder&) = delete;
    TempFolder& operator=(const TempFolder&) = delete;
};

}  // namespace rgbd::cli
