// io::OutputFile: a regular file appears whole at commit() or not at all; /dev/null, /dev/full
// and FIFOs are written in place and stay what they are.
#include "io/output_file.hpp"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <thread>

#include "tests/support/input_error.hpp"
#include "tests/support/temp_dir.hpp"
#include "toolkit/error.hpp"

namespace {

namespace fs = std::filesystem;
using rgbd::IoError;
using rgbd::io::OutputFile;

std::string slurp(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::size_t entries(const fs::path& dir) {
    return static_cast<std::size_t>(std::distance(fs::directory_iterator(dir), {}));
}

template <class F>
std::string io_error_of(F&& f) {
    return rgbd::test::error_message<IoError>(f);
}

TEST(OutputFile, RegularFileAppearsWholeAtCommitAndOldFileStaysUntilThen) {
    const fs::path dir = rgbd::test::fresh_temp_dir("output_file", "commit");
    const fs::path target = dir / "out.ply";
    { std::ofstream(target) << "old"; }
    {
        OutputFile file(target);
        EXPECT_FALSE(file.in_place());
        file.stream() << "new content";
        EXPECT_EQ(slurp(target), "old");  // readers see the old file while writing goes on
        EXPECT_EQ(entries(dir), 2u);      // and the temporary beside it
        file.commit();
    }
    EXPECT_EQ(slurp(target), "new content");
    EXPECT_EQ(entries(dir), 1u);
    fs::remove_all(dir);
}

TEST(OutputFile, WithoutCommitNothingChanges) {
    const fs::path dir = rgbd::test::fresh_temp_dir("output_file", "abandon");
    { std::ofstream(dir / "kept.ply") << "old"; }
    {
        OutputFile file(dir / "kept.ply");
        file.stream() << "half";
    }
    try {
        OutputFile file(dir / "new.ply");
        file.stream() << "half";
        throw std::runtime_error("failed mid-way");
    } catch (const std::runtime_error&) {
    }
    EXPECT_EQ(slurp(dir / "kept.ply"), "old");
    EXPECT_EQ(entries(dir), 1u);  // no new.ply, no temporaries
    fs::remove_all(dir);
}

TEST(OutputFile, BadPathsNameTheOutputAndTheProblem) {
    const fs::path dir = rgbd::test::fresh_temp_dir("output_file", "bad");
    EXPECT_EQ(io_error_of([&] { OutputFile f(dir / "missing" / "x.ply", "-o x.ply"); }),
              "-o x.ply: folder " + (dir / "missing").string() + " does not exist");
    EXPECT_EQ(io_error_of([&] { OutputFile f(dir); }), dir.string() + ": is a folder, not a file");
    EXPECT_EQ(io_error_of([&] { rgbd::io::check_output_path(dir / ""); }),
              (dir / "").string() + ": is a folder, not a file");
    EXPECT_EQ(io_error_of([&] { rgbd::io::check_output_path(dir / "new" / ""); }),
              (dir / "new" / "").string() + ": not a file name");
    EXPECT_NO_THROW(rgbd::io::check_output_path(dir / "fine.ply"));
    EXPECT_EQ(entries(dir), 0u);
    fs::remove_all(dir);
}

TEST(OutputFile, DevicesAreWrittenInPlaceAndAFailedWriteIsAnError) {
    {
        OutputFile null("/dev/null");
        EXPECT_TRUE(null.in_place());
        null.stream() << "discarded";
        null.commit();
    }
    EXPECT_EQ(fs::status("/dev/null").type(), fs::file_type::character);
    if (!fs::exists("/dev/full")) GTEST_SKIP() << "no /dev/full here";
    OutputFile full("/dev/full", "-o /dev/full");
    full.stream() << std::string(1 << 16, 'x');
    EXPECT_EQ(io_error_of([&] { full.commit(); }), "-o /dev/full: write failed (disk full?)");
    EXPECT_EQ(fs::status("/dev/full").type(), fs::file_type::character);
}

TEST(OutputFile, FifoStaysAFifoAndCarriesTheData) {
    const fs::path dir = rgbd::test::fresh_temp_dir("output_file", "fifo");
    const fs::path fifo = dir / "stream.ply";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    std::string got;
    std::thread reader([&] { got = slurp(fifo); });
    {
        OutputFile file(fifo);
        EXPECT_TRUE(file.in_place());
        file.stream() << "through the pipe";
        file.commit();
    }
    reader.join();
    EXPECT_EQ(got, "through the pipe");
    EXPECT_EQ(fs::status(fifo).type(), fs::file_type::fifo);
    fs::remove_all(dir);
}

}  // namespace
