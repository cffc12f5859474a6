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

}  // namespace rgbd::io
