// Object extraction against known answers (issue 35): rgbd-synth renders an egg-shaped subject
// standing on a floor in a room (two walls, clutter, a person outside the ring) with a truth
// label per depth pixel (gt/<sensor>/segment/: 1 subject, 2 support, 3 background, 4 stray
// return); rgbd-cloud's default extraction must keep the subject's points and drop the rest.
// Precision and recall are counted per point from the labels of the points' pixels, against
// the same views without extraction (--no-extract).
#include <gtest/gtest.h>

#include <array>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <opencv2/imgcodecs.hpp>

#include "io/ply_stream.hpp"
#include "tests/support/ellipsoid_off.hpp"
#include "tests/support/tool_runner.hpp"
#include "toolkit/point_cloud.hpp"

namespace fs = std::filesystem;

namespace {

RGBD_TOOL_TEST_SCRATCH("rgbd_extraction_scene_test")

/// Points per truth label (0-4) of a view stream of capture `cap`.
std::array<std::size_t, 5> count_labels(const fs::path& stream, const fs::path& cap) {
    std::array<std::size_t, 5> counts{};
    std::ifstream in(stream, std::ios::binary);
    rgbd::io::PlyStreamReader reader(in, stream.string());
    rgbd::io::Document doc;
    while (reader.next(doc)) {
        const rgbd::PointCloud& view = doc.cloud;
        // rgbd:view.source is CAP/<sensor>/depth/NNNNNN.png; the labels are in
        // gt/<sensor>/segment/.
        const fs::path source(view.view.source);
        const std::string sensor = source.parent_path().parent_path().filename().string();
        const fs::path labels = cap / "gt" / sensor / "segment" / source.filename();
        const cv::Mat image = cv::imread(labels.string(), cv::IMREAD_UNCHANGED);
        EXPECT_FALSE(image.empty()) << labels;
        if (image.empty()) return counts;
        const auto pixels = view.pixel_map();
        EXPECT_TRUE(pixels.has_value());
        if (!pixels) return counts;
        for (auto i : view.points) {
            const std::uint32_t px = (*pixels)[i];
            const std::uint8_t label = image.ptr<std::uint8_t>(0)[px];
            counts[std::min<std::uint8_t>(label, 4)] += 1;
        }
        doc = rgbd::io::Document{};
    }
    return counts;
}

/// Points of a view stream of the APC shelf capture on (first) and off (second) the toolbox's
/// object masks of their pixels: masks/frame-NNNNNN.<object>.mask.png, 16-bit confidence, the
/// object where it reaches <object>.thresh.txt (a fraction of 65535).
std::pair<std::size_t, std::size_t> count_on_masks(const fs::path& stream, const fs::path& cap) {
    std::size_t on = 0, off = 0;
    std::ifstream in(stream, std::ios::binary);
    rgbd::io::PlyStreamReader reader(in, stream.string());
    rgbd::io::Document doc;
    while (reader.next(doc)) {
        const rgbd::PointCloud& view = doc.cloud;
        // rgbd:view.source is CAP/frame-NNNNNN.depth.png.
        const std::string frame = fs::path(view.view.source).filename().string().substr(0, 12);
        cv::Mat objects;
        for (const auto& e : fs::directory_iterator(cap / "masks")) {
            const std::string name = e.path().filename().string();
            if (name.rfind(frame + ".", 0) != 0 || name.find(".mask.png") == std::string::npos)
                continue;
            const cv::Mat m = cv::imread(e.path().string(), cv::IMREAD_UNCHANGED);
            const std::string object =
                name.substr(frame.size() + 1, name.size() - frame.size() - 1 - 9);  // .mask.png
            double thresh = -1;
            std::ifstream(cap / "masks" / (object + ".thresh.txt")) >> thresh;
            EXPECT_TRUE(!m.empty() && thresh > 0 && thresh < 1) << e.path();
            if (m.empty() || !(thresh > 0)) continue;
            if (objects.empty()) objects = cv::Mat::zeros(m.size(), CV_8U);
            objects.setTo(1, m >= thresh * 65535.0);
        }
        EXPECT_FALSE(objects.empty()) << "no masks of " << frame;
        const auto pixels = view.pixel_map();
        EXPECT_TRUE(pixels.has_value());
        if (objects.empty() || !pixels) return {on, off};
        for (auto i : view.points) {
            const bool object = objects.ptr<std::uint8_t>(0)[(*pixels)[i]] != 0;
            on += object, off += !object;
        }
        doc = rgbd::io::Document{};
    }
    return {on, off};
}

}  // namespace

TEST(ExtractionScene, KeepsTheSubjectAndDropsFloorWallsClutterAndPeople) {
    // An upright egg 0.4 m tall standing on the floor of a room.
    rgbd::test::write_ellipsoid_off(temp_root() / "egg.off", 48, 24, 0.12, 0.2, 0.1);
    ASSERT_EQ(run("$BIN/rgbd-synth egg.off -o room --height-m 0.4 --scene room "
                  "--resolution-scale 0.5 --seed 2 -q")
                  .code,
              0);
    ASSERT_EQ(run("$BIN/rgbd-cloud room --no-extract -o all.ply -q").code, 0);
    ASSERT_EQ(run("$BIN/rgbd-cloud room -o kept.ply --metrics kept.json -q").code, 0);
    const auto all = count_labels(temp_root() / "all.ply", temp_root() / "room");
    const auto kept = count_labels(temp_root() / "kept.ply", temp_root() / "room");
    ASSERT_GT(all[1], 5000u);
    ASSERT_GT(all[2], 10000u);
    ASSERT_GT(all[3], 10000u);
    const double kept_total = kept[1] + kept[2] + kept[3] + kept[4];
    // Stray returns (flying pixels) carry their pixel's surface label; the distance cleaning
    // removes them next, so the precision is judged after it too.
    std::cout << "room: precision " << kept[1] / kept_total << ", recall "
              << static_cast<double>(kept[1]) / all[1] << "\n";
    EXPECT_GE(kept[1] / kept_total, 0.95) << "precision";
    ASSERT_EQ(run("$BIN/rgbd-clean --distance kept.ply -o kept_clean.ply -q").code, 0);
    const auto clean = count_labels(temp_root() / "kept_clean.ply", temp_root() / "room");
    EXPECT_GE(clean[1] / static_cast<double>(clean[1] + clean[2] + clean[3] + clean[4]), 0.97)
        << "precision after rgbd-clean --distance";
    // The subject loses its last millimetres above the floor (the noise margin of the cut).
    EXPECT_GE(static_cast<double>(kept[1]) / all[1], 0.90) << "recall";
    EXPECT_LE(static_cast<double>(kept[2]) / all[2], 0.01) << "floor kept";
    EXPECT_LE(static_cast<double>(kept[3]) / all[3], 0.01) << "walls, clutter, people kept";
    // The ground was found at the egg's foot and written into the metrics.
    const auto m = read_json(temp_root() / "kept.json");
    EXPECT_TRUE(m["extraction"]["ground"]["found"].get<bool>()) << m["extraction"].dump();
}

TEST(ExtractionScene, KeepGroundKeepsTheFloor) {
    rgbd::test::write_ellipsoid_off(temp_root() / "egg2.off", 32, 16, 0.12, 0.2, 0.1);
    ASSERT_EQ(run("$BIN/rgbd-synth egg2.off -o floor --height-m 0.4 --floor "
                  "--resolution-scale 0.5 --seed 4 -q")
                  .code,
              0);
    ASSERT_EQ(run("$BIN/rgbd-cloud floor --keep-ground -o with_floor.ply -q").code, 0);
    const auto with_floor = count_labels(temp_root() / "with_floor.ply", temp_root() / "floor");
    EXPECT_GT(with_floor[2], 1000u) << "--keep-ground keeps the floor";
}

// Real data (issue 35 item 6): 15 views of a shelf bin by a RealSense F200 on a robot arm
// (../shared/data/multiview/apc_realsense_f200_shelf, exact arm poses). The bin's floor is seen
// at 73-83 deg incidence; its flatness, judged in units of the sensor's own noise there, makes
// it the ground: it is removed, the bin's three walls too, and the four objects on it are kept
// (the toolbox's object masks tell which pixels are objects).
TEST(ExtractionScene, RealShelfBinFloorIsTheGroundAndTheObjectsAreKept) {
    const fs::path cap = fs::path(RGBD_SHARED_DATA) / "multiview/apc_realsense_f200_shelf";
    if (!fs::exists(cap / "cam.info.txt")) GTEST_SKIP() << "no " << cap;
    ASSERT_EQ(run("$BIN/rgbd-cloud " + cap.string() + " --no-extract -o apc_all.ply -q").code, 0);
    ASSERT_EQ(
        run("$BIN/rgbd-cloud " + cap.string() + " -o apc_kept.ply --metrics apc.json -q").code, 0);
    const auto m = read_json(temp_root() / "apc.json");
    const auto& ground = m["extraction"]["ground"];
    ASSERT_TRUE(ground["found"].get<bool>()) << ground.dump();
    EXPECT_LE(ground["flatness_sigmas"].get<double>(), 3.0) << ground.dump();
    const auto all = count_on_masks(temp_root() / "apc_all.ply", cap);
    const auto kept = count_on_masks(temp_root() / "apc_kept.ply", cap);
    std::cout << "APC points on / off the object masks: all " << all.first << " / " << all.second
              << ", kept " << kept.first << " / " << kept.second << "\n";
    ASSERT_GT(all.first, 100000u);
    ASSERT_GT(all.second, 100000u);
    const double object_kept = static_cast<double>(kept.first) / all.first;
    const double rest_removed = 1.0 - static_cast<double>(kept.second) / all.second;
    std::cout << "APC: object points kept " << object_kept << ", other points removed "
              << rest_removed << "\n";
    // The floor's cut takes the objects' lowest centimetre or two (the margin at grazing
    // incidence is 3 sigma_z of 3-6 mm) and the masks' fringes. The back wall and both side
    // walls are walls (flat, nothing seen through them, every sensor in front of them) and are
    // cut. A plane through a side wall and the objects leaning on it (11-15 degrees off) is
    // refused (not flat, or the wall seen through it in the views); the refused slices'
    // samples, searched again with a 10-degree cone, give the second side wall. Each view's
    // cut lies at the mode of the wall's heights, with the noise measured behind the wall
    // (a book stands 1-2 cm in front of it). Measured: 68.9% of the object points kept (70.3%
    // when the second side wall stayed: the masks' fringes on the wall go with it), 80.0% of
    // the rest removed (68.5%).
    EXPECT_GE(object_kept, 0.66);
    EXPECT_GE(rest_removed, 0.78);
    std::size_t walls = 0, side_walls[2] = {0, 0}, refused_slices = 0;
    for (const auto& w : m["extraction"]["walls"]) {
        const std::string note = w.value("note", "");
        if (note == "seen through in the views" || note == "not flat in half the views")
            ++refused_slices;
        if (!w["found"].get<bool>()) continue;
        ++walls;
        const double ny = w["normal"][1].get<double>();
        if (std::abs(ny) > 0.99) ++side_walls[ny > 0];
        EXPECT_LE(w["view_through_share"].get<double>(), 0.005) << w.dump();
    }
    EXPECT_GE(walls, 3u) << m["extraction"]["walls"].dump();
    EXPECT_GE(side_walls[0], 1u) << m["extraction"]["walls"].dump();
    EXPECT_GE(side_walls[1], 1u) << m["extraction"]["walls"].dump();
    EXPECT_GE(refused_slices, 1u) << m["extraction"]["walls"].dump();
}
