// Output paths that are not regular files: /dev/null, /dev/stdout, a FIFO.
#pragma once

#include <filesystem>

namespace rgbd::io {

/// True when `path` names an existing file that is not a regular file or a folder (a character
/// device such as /dev/null or /dev/stdout, a FIFO, a socket; symbolic links are followed).
/// Output for such a path is written to it in place: renaming a temporary file over it, as the
/// atomic writers do for regular files (a failed run leaves the old file or none), would
/// replace the device or the FIFO with a regular file.
bool writes_in_place(const std::filesystem::path& path);

}  // namespace rgbd::io
