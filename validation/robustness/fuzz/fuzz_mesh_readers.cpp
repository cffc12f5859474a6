// libFuzzer target: the single-file readers of io/mesh_io.hpp. The first byte picks the file
// extension (ply, off, obj, pcd, xyz); the rest is the file. read_mesh and read_point_cloud
// both read it.
#include "io/mesh_io.hpp"
#include "validation/robustness/fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size < 1) return 0;
    static const char* const kExt[] = {".ply", ".off", ".obj", ".pcd", ".xyz"};
    const auto path = rgbd::fuzz::scratch() / (std::string("input") + kExt[data[0] % 5]);
    rgbd::fuzz::write_file(path, data + 1, size - 1);
    rgbd::fuzz::expect_clean([&] { rgbd::io::read_mesh(path); });
    rgbd::fuzz::expect_clean([&] { rgbd::io::read_point_cloud(path); });
    return 0;
}
