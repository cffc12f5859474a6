#include "io/output_file.hpp"

#include <unistd.h>

#include <atomic>
#include <system_error>
#include <utility>

#include "toolkit/error.hpp"

namespace rgbd::io {

namespace fs = std::filesystem;

bool writes_in_place(const fs::path& path) {
    std::error_code ec;
    const fs::file_status s = fs::status(path, ec);
    if (ec || !fs::exists(s)) return false;
    return !fs::is_regular_file(s) && !fs::is_directory(s);
}

void check_output_path(const fs::path& path, const std::string& label) {
    const std::string name = label.empty() ? path.string() : label;
    if (fs::is_directory(path)) throw IoError(name + ": is a folder, not a file");
    if (path.filename().empty()) throw IoError(name + ": not a file name");
    const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
    if (!fs::is_directory(dir))
        throw IoError(name + ": folder " + dir.string() + " does not exist");
}

namespace {
fs::path temporary_beside(const fs::path& path) {
    static std::atomic<unsigned> counter{0};
    std::string name(1, '.');
    name.append(path.filename().string());
    name.append(".tmp-");
    name.append(std::to_string(::getpid()));
    name.push_back('-');
    name.append(std::to_string(counter++));
    return path.parent_path() / name;
}
}  // namespace

OutputFile::OutputFile(const fs::path& path, std::string label)
    : path_(path), label_(label.empty() ? path.string() : std::move(label)) {
    check_output_path(path_, label_);
    if (!writes_in_place(path_)) temporary_ = temporary_beside(path_);
    out_.open(in_place() ? path_ : temporary_, std::ios::binary | std::ios::trunc);
    if (!out_.is_open()) {
        temporary_.clear();  // nothing was created
        throw IoError(label_ + ": cannot open for writing");
    }
}

OutputFile::~OutputFile() {
    if (out_.is_open()) out_.close();
    if (!temporary_.empty()) {
        std::error_code ignored;
        fs::remove(temporary_, ignored);  // not committed: leave nothing behind
    }
}

bool OutputFile::close() {
    if (closed_) return ok_;
    closed_ = true;
    out_.flush();
    ok_ = out_.good();
    out_.close();
    ok_ = ok_ && !out_.fail();
    return ok_;
}

void OutputFile::commit() {
    if (!close()) throw IoError(label_ + ": write failed (disk full?)");
    if (temporary_.empty()) return;
    std::error_code ec;
    fs::rename(temporary_, path_, ec);
    if (ec) throw IoError(label_ + ": cannot rename into place: " + ec.message());
    temporary_.clear();
}

void write_folder_atomic(const fs::path& target_in,
                         const std::function<void(const fs::path& folder)>& fill,
                         const FolderPolicy& policy) {
    if (target_in.empty()) throw IoError("output folder name is empty");
    const fs::path absolute = fs::absolute(target_in).lexically_normal();
    const fs::path target = absolute.has_filename() ? absolute : absolute.parent_path();
    const std::string name = target.string();
    std::error_code ec;
    const bool existed = fs::exists(target, ec);
    if (existed) {
        if (!fs::is_directory(target)) throw IoError(name + ": exists and is not a folder");
        const std::string why =
            policy.refuse ? policy.refuse(target)
                          : (fs::is_empty(target) ? "" : "folder exists and is not empty");
        if (!why.empty()) throw IoError(name + ": " + why);
    }
    const fs::path parent = target.parent_path();
    if (policy.create_parent) {
        fs::create_directories(parent, ec);
        if (ec) throw IoError(parent.string() + ": cannot create folder: " + ec.message());
    } else if (!fs::is_directory(parent)) {
        throw IoError(name + ": folder " + parent.string() + " does not exist");
    }
    const fs::path temporary = temporary_beside(target);
    const fs::path old = temporary.string() + "-old";
    fs::remove_all(temporary, ec);
    if (!fs::create_directory(temporary, ec) || ec)
        throw IoError(temporary.string() + ": cannot create folder: " + ec.message());
    try {
        try {
            fill(temporary);
        } catch (const fs::filesystem_error& e) {
            throw IoError(name + ": " + e.what());
        }
        if (existed) {
            fs::rename(target, old, ec);
            if (ec) throw IoError(name + ": cannot move the old folder aside: " + ec.message());
        }
        fs::rename(temporary, target, ec);
        if (ec) {
            std::error_code ignored;
            if (existed) fs::rename(old, target, ignored);
            throw IoError(name + ": cannot rename into place: " + ec.message());
        }
    } catch (...) {
        std::error_code ignored;
        fs::remove_all(temporary, ignored);
        throw;
    }
    if (existed) fs::remove_all(old, ec);
}

}  // namespace rgbd::io
