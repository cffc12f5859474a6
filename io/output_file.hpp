// Output files that appear whole or not at all, and outputs that are not regular files
// (/dev/null, /dev/stdout, a FIFO), which are written in place.
#pragma once

#include <filesystem>
#include <fstream>
#include <functional>
#include <ostream>
#include <string>

namespace rgbd::io {

/// True when `path` names an existing file that is not a regular file or a folder (a character
/// device such as /dev/null or /dev/stdout, a FIFO, a socket; symbolic links are followed).
/// Output for such a path is written to it in place: renaming a temporary file over it, as the
/// atomic writers do for regular files (a failed run leaves the old file or none), would
/// replace the device or the FIFO with a regular file.
bool writes_in_place(const std::filesystem::path& path);

/// Throws IoError "<label>: ..." when `path` cannot name an output file: it is a folder, it
/// has no file name, or its folder does not exist. `label` is how messages name the output (the
/// path itself when empty). Touches nothing.
void check_output_path(const std::filesystem::path& path, const std::string& label = {});

/// One output file, written through a stream that stays open as long as the writer needs it
/// (a whole run of a tool, a live stream) and put in place by commit(): a regular file is
/// written to a temporary file beside `path` (".<name>.tmp-<pid>-<n>") that commit() renames
/// over `path`, so readers never see half a file and a failed run leaves the old file or none;
/// a path that writes_in_place() is opened and written directly. An OutputFile destroyed
/// without commit() removes its temporary file.
class OutputFile {
public:
    /// Opens the stream (binary, truncating). IoError from check_output_path(), or
    /// "<label>: cannot open for writing".
    explicit OutputFile(const std::filesystem::path& path, std::string label = {});
    ~OutputFile();
    OutputFile(const OutputFile&) = delete;
    OutputFile& operator=(const OutputFile&) = delete;

    std::ostream& stream() { return out_; }
    /// True when the path is written directly (no temporary, no rename).
    bool in_place() const { return temporary_.empty(); }
    /// Flushes and closes the stream (again: no effect); false when a write failed.
    bool close();
    /// close(), then renames the temporary over the path. IoError "<label>: write failed (disk
    /// full?)" when a write failed, "<label>: cannot rename into place: <reason>".
    void commit();

private:
    std::filesystem::path path_;
    std::string label_;
    std::filesystem::path temporary_;  ///< empty when in_place()
    std::ofstream out_;
    bool ok_ = true;  ///< every write so far succeeded (known after close())
    bool closed_ = false;
};

/// How write_folder_atomic treats the target's surroundings.
struct FolderPolicy {
    /// Create the target's parent folders when missing (otherwise: IoError).
    bool create_parent = false;
    /// Why an existing `target` may not be replaced, "" when it may. Empty function: only an
    /// empty folder may be (a non-empty one is "folder exists and is not empty").
    std::function<std::string(const std::filesystem::path& target)> refuse;
};

/// Writes a folder that appears whole or not at all: `fill` writes into a new, empty
/// temporary folder beside `target` (".<name>.tmp-<pid>-<n>"), which is then renamed to
/// `target`; an existing `target` that `policy` lets go is moved aside first and removed once
/// the new folder is in place. IoError "<target>: ..." when the parent folder does not exist,
/// `target` is not a folder or is refused, or a rename fails. An exception from `fill`
/// propagates after the temporary folder is removed (a std::filesystem error as IoError naming
/// `target`); `target` is then as it was.
void write_folder_atomic(const std::filesystem::path& target,
                         const std::function<void(const std::filesystem::path& folder)>& fill,
                         const FolderPolicy& policy = {});

}  // namespace rgbd::io
