#include "io/internal/atomic_file.hpp"

#include <unistd.h>

#include <atomic>
#include <fstream>
#include <string>
#include <system_error>

#include "io/output_path.hpp"
#include "toolkit/error.hpp"

namespace rgbd::io::internal {

namespace {
std::filesystem::path temporary_path(const std::filesystem::path& path) {
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

void write_file_atomic(const std::filesystem::path& path,
                       const std::function<void(std::ostream&)>& fill) {
    if (path.filename().empty()) throw IoError(path.string() + ": not a file name");
    if (writes_in_place(path)) {  // /dev/null, /dev/stdout, a FIFO: no temporary, no rename
        std::ofstream out(path, std::ios::binary);
        if (!out) throw IoError(path.string() + ": cannot open for writing");
        fill(out);
        out.flush();
        if (!out) throw IoError(path.string() + ": write failed");
        return;
    }
    const std::filesystem::path tmp = temporary_path(path);
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out)
        throw IoError(path.string() + ": cannot create file (folder missing or not writable)");
    try {
        fill(out);
        out.flush();
        if (!out) throw IoError(path.string() + ": write failed (disk full?)");
        out.close();
        if (out.fail()) throw IoError(path.string() + ": write failed on close (disk full?)");
        std::error_code ec;
        std::filesystem::rename(tmp, path, ec);
        if (ec) throw IoError(path.string() + ": cannot rename temporary file: " + ec.message());
    } catch (...) {
        if (out.is_open()) out.close();
        std::error_code ignored;
        std::filesystem::remove(tmp, ignored);
        throw;
    }
}

}  // namespace rgbd::io::internal
