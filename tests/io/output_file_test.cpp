// io::OutputFile: a regular file appears whole at commit() or not at all; /dev/null, /dev/full
// and FIFOs are written in place and stay what they are. io::write_folder_atomic: a folder
// appears whole or not at all.
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

namespace folder_tests {

using rgbd::io::FolderPolicy;
using rgbd::io::write_folder_atomic;

void write_one(const fs::path& folder, const std::string& text) {
    std::ofstream(folder / "a.txt") << text;
}

TEST(WriteFolderAtomic, NewFolderAppearsWholeAndAnEmptyOneIsReplaced) {
    const fs::path dir = rgbd::test::fresh_temp_dir("output_folder", "new");
    write_folder_atomic(dir / "cap", [](const fs::path& f) { write_one(f, "one"); });
    EXPECT_EQ(slurp(dir / "cap" / "a.txt"), "one");
    fs::create_directory(dir / "empty");
    write_folder_atomic(dir / "empty/", [](const fs::path& f) { write_one(f, "two"); });
    EXPECT_EQ(slurp(dir / "empty" / "a.txt"), "two");
    EXPECT_EQ(entries(dir), 2u);  // no temporaries left
    fs::remove_all(dir);
}

TEST(WriteFolderAtomic, RefusedOrFailedLeavesTheTargetAsItWas) {
    const fs::path dir = rgbd::test::fresh_temp_dir("output_folder", "refuse");
    write_folder_atomic(dir / "cap", [](const fs::path& f) { write_one(f, "old"); });
    EXPECT_EQ(io_error_of([&] { write_folder_atomic(dir / "cap", [](const fs::path&) {}); }),
              (dir / "cap").string() + ": folder exists and is not empty");
    EXPECT_THROW(write_folder_atomic(dir / "cap2",
                                     [](const fs::path& f) {
                                         write_one(f, "half");
                                         throw IoError("disk full");
                                     }),
                 IoError);
    EXPECT_EQ(
        io_error_of([&] { write_folder_atomic(dir / "no" / "cap", [](const fs::path&) {}); }),
        (dir / "no" / "cap").string() + ": folder " + (dir / "no").string() + " does not exist");
    EXPECT_EQ(slurp(dir / "cap" / "a.txt"), "old");
    EXPECT_EQ(entries(dir), 1u);
    fs::remove_all(dir);
}

TEST(WriteFolderAtomic, APolicyMayReplaceAFullFolderAndCreateParents) {
    const fs::path dir = rgbd::test::fresh_temp_dir("output_folder", "policy");
    FolderPolicy policy;
    policy.create_parent = true;
    policy.refuse = [](const fs::path& t) {
        return fs::exists(t / "a.txt") ? std::string() : std::string("not ours");
    };
    const fs::path target = dir / "deep" / "report";
    write_folder_atomic(
        target, [](const fs::path& f) { write_one(f, "first"); }, policy);
    write_folder_atomic(
        target, [](const fs::path& f) { write_one(f, "second"); }, policy);
    EXPECT_EQ(slurp(target / "a.txt"), "second");
    EXPECT_EQ(entries(dir / "deep"), 1u);  // the old folder moved aside is gone
    fs::create_directories(dir / "other");
    std::ofstream(dir / "other" / "keep.txt") << "x";
    EXPECT_EQ(io_error_of([&] {
                  write_folder_atomic(
                      dir / "other", [](const fs::path&) {}, policy);
              }),
              (dir / "other").string() + ": not ours");
    EXPECT_TRUE(fs::exists(dir / "other" / "keep.txt"));
    fs::remove_all(dir);
}

}  // namespace folder_tests

}  // namespace
