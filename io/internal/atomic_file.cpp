#include "io/internal/atomic_file.hpp"

#include "io/output_file.hpp"

namespace rgbd::io::internal {

void write_file_atomic(const std::filesystem::path& path,
                       const std::function<void(std::ostream&)>& fill) {
    OutputFile file(path);
    fill(file.stream());  // an exception leaves the temporary to the destructor
    file.commit();
}

}  // namespace rgbd::io::internal
