#include "algorithms/texture/texture_mesh.hpp"

#include "toolkit/error.hpp"
#include "toolkit/pose.hpp"

namespace rgbd::texture {

void TextureOptions::check() const {
    refine.check();
    selection.check();
    adjust.check();
    consistency.check();
    levelling.check();
    atlas.check();
}

TexturedMesh texture_mesh(const Mesh& mesh, const std::vector<TextureView>& input_views,
                          const TextureOptions& options, Report& report, const Progress& progress) {
    options.check();
    RGBD_CHECK(!input_views.empty(), "texture: no colour images");
    Stopwatch watch;
    const TexturedMesh plain = untextured(mesh);
    const render::RenderScene scene(plain.vertices, plain.faces);
    const auto& tris = scene.triangles();
    report["faces"] = tris.size();
    report["views"] = input_views.size();
    // The colour cameras' poses refined against the mesh (shallow copies of the images).
    std::vector<TextureView> refined;
    if (options.refine.enabled) {
        Report refine;
        const std::vector<Pose> poses =
            refine_colour_poses(scene, input_views, options.refine, refine);
        refined = input_views;
        for (std::size_t v = 0; v < refined.size(); ++v) refined[v].world_from_camera = poses[v];
        report["refine"] = refine;
    }
    const std::vector<TextureView>& views = options.refine.enabled ? refined : input_views;

    FaceQuality quality = face_quality(scene, views, options.selection, [&](double f) {
        return report_progress(progress, 0.7 * f);
    });
    report["quality_time_s"] = watch.seconds();

    // The global gains first: the photo-consistency test compares adjusted colours.
    Stopwatch adjust_watch;
    Report adjust;
    const std::vector<ColourGain> gains =
        adjust_colours(scene, views, quality, options.adjust, adjust);
    adjust["time_s"] = adjust_watch.seconds();
    report["adjust"] = adjust;
    Stopwatch consistency_watch;
    Report consistency;
    reject_inconsistent_views(scene, views, gains, options.consistency, quality, consistency);
    consistency["time_s"] = consistency_watch.seconds();
    report["consistency"] = consistency;

    Stopwatch selection_watch;
    const auto adjacency = face_adjacency(tris);
    const Selection selection = select_views(quality, adjacency, options.selection);
    if (selection.unseen == tris.size())
        throw InputError("no face of the mesh is seen by any of the " +
                         std::to_string(views.size()) +
                         " colour cameras (wrong poses, or a mesh of another capture?)");
    Report sel;
    sel["method"] = "ICM (Potts smoothness)";
    sel["unseen_faces"] = selection.unseen;
    sel["relabelled_faces"] = selection.relabelled;
    sel["sweeps"] = selection.sweeps_run;
    Report per_view = Report::array();
    std::vector<std::size_t> count(views.size(), 0);
    for (const int l : selection.label)
        if (l >= 0) ++count[l];
    for (std::size_t v = 0; v < views.size(); ++v)
        per_view.push_back({{"view", views[v].name}, {"faces", count[v]}});
    sel["views"] = per_view;
    sel["time_s"] = selection_watch.seconds();
    report["selection"] = sel;
    report_progress(progress, 0.8);

    // Flat colours of unseen faces: the mean of their vertices' colours (grey without any).
    std::vector<Rgb> flat(tris.size(), Rgb{128, 128, 128});
    if (!plain.vertex_colors.empty())
        for (std::size_t f = 0; f < tris.size(); ++f) {
            if (selection.label[f] >= 0) continue;
            int sum[3] = {0, 0, 0};
            for (const int v : tris[f]) {
                sum[0] += plain.vertex_colors[v].r;
                sum[1] += plain.vertex_colors[v].g;
                sum[2] += plain.vertex_colors[v].b;
            }
            flat[f] = {static_cast<std::uint8_t>((sum[0] + 1) / 3),
                       static_cast<std::uint8_t>((sum[1] + 1) / 3),
                       static_cast<std::uint8_t>((sum[2] + 1) / 3)};
        }
    const std::vector<Chart> charts = make_charts(selection.label, adjacency);
    Report levelling;
    const SeamCorrections seams =
        level_seams(scene, views, gains, charts, adjacency, options.levelling, levelling);
    report["levelling"] = levelling;
    report_progress(progress, 0.9);
    Stopwatch atlas_watch;
    Report atlas;
    TexturedMesh out = build_atlas(scene, views, charts, gains, flat, options.atlas, atlas,
                                   options.levelling.enabled ? &seams : nullptr);
    atlas["time_s"] = atlas_watch.seconds();
    report["atlas"] = atlas;
    out.vertex_colors = plain.vertex_colors;
    // The world's up as the colour cameras see it (a .glb turns it to +Y), as the pipeline's
    // closure finds it (pipeline/stages.cpp): none when the cameras disagree.
    std::vector<Pose> cameras;
    for (const auto& v : views) cameras.push_back(v.world_from_camera);
    out.up = sensors_up(cameras, 0.7);
    if (out.up) report["up"] = {out.up->x(), out.up->y(), out.up->z()};
    report["time_s"] = watch.seconds();
    report_progress(progress, 1.0);
    return out;
}

}  // namespace rgbd::texture
