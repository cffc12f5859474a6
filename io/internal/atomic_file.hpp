// Atomic file writing for io/: the content goes to a temporary file in the destination's
// folder, which is renamed over the destination only when everything was written. On any
// error the temporary file is removed and the destination is left untouched. A destination
// that is not a regular file (/dev/null, a FIFO) is written in place; both by io::OutputFile
// (io/output_file.hpp). See also: io/mesh_io.hpp, io/capture_folder.hpp (write_text_atomic,
// write_image_atomic).
#pragma once

#include <filesystem>
#include <functional>
#include <ostream>

namespace rgbd::io::internal {

/// Calls `fill` with a binary output stream on a temporary file beside `path`, then renames
/// it to `path`. Exceptions from `fill` propagate after the temporary file is removed;
/// stream failures throw IoError naming `path`.
void write_file_atomic(const std::filesystem::path& path,
                       const std::function<void(std::ostream&)>& fill);

}  // namespace rgbd::io::internal
