#include "algorithms/texture/atlas.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <unordered_map>

#include "algorithms/internal/ring_dilation.hpp"
#include "algorithms/texture/seam_levelling.hpp"
#include "toolkit/error.hpp"

namespace rgbd::texture {
namespace {

/// A rectangle to place: a chart's image rectangle or a flat cell.
struct Item {
    int chart = -1;             ///< index into charts, -1 = flat cell
    cv::Rect source;            ///< chart: the rectangle of its image
    int width = 0, height = 0;  ///< size in the atlas, texels
    int atlas = -1, x = 0, y = 0;
};

int next_pow2(double v) {
    int p = 1;
    while (p < v && p < (1 << 20)) p <<= 1;
    return p;
}

/// Shelf packing (next fit, items in the given order) into atlases of `side` x `side`; opens a
/// new atlas when an item does not fit below the last shelf, unless `single`. Returns the
/// number of atlases used and fills heights (used rows per atlas), or 0 when `single` and the
/// items do not fit into one.
int shelf_pack(std::vector<Item>& items, const std::vector<std::size_t>& order, int side,
               bool single, std::vector<int>& heights) {
    heights.assign(1, 0);
    int atlas = 0, x = 0, y = 0, shelf = 0;
    for (const std::size_t i : order) {
        Item& it = items[i];
        if (it.width > side || it.height > side) return 0;
        if (x + it.width > side) {  // next shelf
            y += shelf;
            x = 0;
            shelf = 0;
        }
        if (y + it.height > side) {  // next atlas
            if (single) return 0;
            ++atlas;
            heights.push_back(0);
            x = y = shelf = 0;
        }
        it.atlas = atlas;
        it.x = x;
        it.y = y;
        x += it.width;
        shelf = std::max(shelf, it.height);
        heights[atlas] = std::max(heights[atlas], y + shelf);
    }
    return atlas + 1;
}

/// The texels of a chart's rectangle whose centres lie inside one of its faces (`texel_of`: each
/// vertex's position in texel units, texel (x, y) covering [x, x + 1) x [y, y + 1)); a face too
/// small to hold a texel centre marks the texel under its centroid.
cv::Mat chart_mask(cv::Size size, const std::vector<std::array<int, 3>>& faces,
                   const std::unordered_map<int, Eigen::Vector2d>& texel_of) {
    cv::Mat mask(size, CV_8U, cv::Scalar(0));
    for (const auto& t : faces) {
        const Eigen::Vector2d &p0 = texel_of.at(t[0]), &p1 = texel_of.at(t[1]),
                              &p2 = texel_of.at(t[2]);
        const double det =
            (p1.x() - p0.x()) * (p2.y() - p0.y()) - (p2.x() - p0.x()) * (p1.y() - p0.y());
        bool any = false;
        if (std::abs(det) > 1e-12) {
            const int x0 =
                std::max(0, static_cast<int>(std::floor(std::min({p0.x(), p1.x(), p2.x()}))));
            const int y0 =
                std::max(0, static_cast<int>(std::floor(std::min({p0.y(), p1.y(), p2.y()}))));
            const int x1 =
                std::min(size.width - 1, static_cast<int>(std::max({p0.x(), p1.x(), p2.x()})));
            const int y1 =
                std::min(size.height - 1, static_cast<int>(std::max({p0.y(), p1.y(), p2.y()})));
            for (int y = y0; y <= y1; ++y)
                for (int x = x0; x <= x1; ++x) {
                    const double px = x + 0.5, py = y + 0.5;
                    const double b1 =
                        ((px - p0.x()) * (p2.y() - p0.y()) - (p2.x() - p0.x()) * (py - p0.y())) /
                        det;
                    const double b2 =
                        ((p1.x() - p0.x()) * (py - p0.y()) - (px - p0.x()) * (p1.y() - p0.y())) /
                        det;
                    if (b1 < -1e-9 || b2 < -1e-9 || b1 + b2 > 1 + 1e-9) continue;
                    mask.at<uchar>(y, x) = 1;
                    any = true;
                }
        }
        if (!any) {
            const Eigen::Vector2d c = (p0 + p1 + p2) / 3.0;
            mask.at<uchar>(std::clamp(static_cast<int>(c.y()), 0, size.height - 1),
                           std::clamp(static_cast<int>(c.x()), 0, size.width - 1)) = 1;
        }
    }
    return mask;
}

/// Texels outside `mask` take the mean of their masked 8-neighbours, ring by ring, `rings`
/// times: a chart's padding repeats its own border texels instead of the image's pixels beyond
/// it, which at the chart's silhouette in its image are the background (light specks along the
/// charts' borders under bilinear lookups and mip-mapping). Texels further out keep the image.
void pad_from_chart(cv::Mat& target, cv::Mat mask, int rings) {
    rgbd::internal::dilate_covered<uchar>(target, mask, rings);
}

}  // namespace

void AtlasOptions::check() const {
    RGBD_CHECK(max_size >= 64 && max_size <= 16384 && (max_size & (max_size - 1)) == 0,
               "texture: the atlas size limit must be a power of two in [64, 16384]");
    RGBD_CHECK(padding_px >= 1 && padding_px <= 64, "texture: padding must be in [1, 64] px");
    RGBD_CHECK(std::isfinite(scale) && scale > 0 && scale <= 1,
               "texture: texel scale must be in (0, 1]");
    RGBD_CHECK(std::isfinite(min_scale) && min_scale > 0 && min_scale <= scale,
               "texture: minimum texel scale must be in (0, scale]");
    RGBD_CHECK(flat_cell_px >= 2 && flat_cell_px <= 64, "texture: flat cells must be 2-64 px");
    RGBD_CHECK(max_flat_cells >= 1 && max_flat_cells <= 1 << 20,
               "texture: max_flat_cells must be in [1, 1048576]");
}

std::vector<Chart> make_charts(const std::vector<int>& label,
                               const std::vector<std::array<int, 3>>& adjacency) {
    std::vector<Chart> charts;
    std::vector<int> chart_of(label.size(), -1);
    std::vector<int> stack;
    for (std::size_t seed = 0; seed < label.size(); ++seed) {
        if (label[seed] < 0 || chart_of[seed] >= 0) continue;
        Chart chart;
        chart.view = label[seed];
        const int id = static_cast<int>(charts.size());
        stack.assign(1, static_cast<int>(seed));
        chart_of[seed] = id;
        while (!stack.empty()) {
            const int f = stack.back();
            stack.pop_back();
            chart.faces.push_back(f);
            for (const int g : adjacency[f])
                if (g >= 0 && chart_of[g] < 0 && label[g] == chart.view) {
                    chart_of[g] = id;
                    stack.push_back(g);
                }
        }
        std::sort(chart.faces.begin(), chart.faces.end());
        charts.push_back(std::move(chart));
    }
    return charts;
}

TexturedMesh build_atlas(const render::RenderScene& scene, const std::vector<TextureView>& views,
                         const std::vector<Chart>& charts, const std::vector<ColourGain>& gains,
                         const std::vector<Rgb>& flat_colour, const AtlasOptions& options,
                         Report& report, const SeamCorrections* seams) {
    options.check();
    const auto& verts = scene.vertices();
    const auto& tris = scene.triangles();
    RGBD_CHECK(flat_colour.size() == tris.size() && gains.size() == views.size() &&
                   (!seams || seams->chart_vertex.size() == charts.size()),
               "texture: build_atlas inputs disagree in size");
    TexturedMesh out;
    out.vertices = verts;
    out.faces = tris;
    out.face_uvs.assign(tris.size(), {-1, -1, -1});
    out.face_atlas.assign(tris.size(), 0);

    // Chart rectangles and the image coordinates of their corners.
    std::vector<Item> items;
    std::vector<std::unordered_map<int, Eigen::Vector2d>> corner_px(charts.size());
    std::vector<char> in_chart(tris.size(), 0);
    for (std::size_t c = 0; c < charts.size(); ++c) {
        const TextureView& view = views[charts[c].view];
        const Pose camera_from_world = view.world_from_camera.inverse();
        double u0 = 1e30, v0 = 1e30, u1 = -1e30, v1 = -1e30;
        for (const int f : charts[c].faces) {
            in_chart[f] = 1;
            for (const int v : tris[f]) {
                auto [it, fresh] = corner_px[c].try_emplace(v);
                if (fresh) it->second = view.intrinsics.project(camera_from_world * verts[v]);
                const Eigen::Vector2d& p = it->second;
                u0 = std::min(u0, p.x());
                v0 = std::min(v0, p.y());
                u1 = std::max(u1, p.x());
                v1 = std::max(v1, p.y());
            }
        }
        const int x0 = std::max(0, static_cast<int>(std::floor(u0)) - options.padding_px);
        const int y0 = std::max(0, static_cast<int>(std::floor(v0)) - options.padding_px);
        const int x1 =
            std::min(view.image.cols - 1, static_cast<int>(std::ceil(u1)) + options.padding_px);
        const int y1 =
            std::min(view.image.rows - 1, static_cast<int>(std::ceil(v1)) + options.padding_px);
        Item it;
        it.chart = static_cast<int>(c);
        it.source = cv::Rect(x0, y0, std::max(1, x1 - x0 + 1), std::max(1, y1 - y0 + 1));
        items.push_back(it);
    }
    // Flat cells: one per quantised colour of the faces in no chart, the finest quantum (levels
    // per channel, a power of two) that needs at most max_flat_cells cells.
    std::vector<int> flat;
    for (std::size_t f = 0; f < tris.size(); ++f)
        if (!in_chart[f]) flat.push_back(static_cast<int>(f));
    const std::size_t flat_faces = flat.size();
    int quantum = 1;
    std::map<std::array<int, 3>, int> bin_of;  // quantised colour -> cell number
    for (;; quantum *= 2) {
        bin_of.clear();
        for (const int f : flat) {
            const Rgb c = flat_colour[f];
            bin_of.try_emplace({c.r / quantum, c.g / quantum, c.b / quantum},
                               static_cast<int>(bin_of.size()));
            if (bin_of.size() > static_cast<std::size_t>(options.max_flat_cells)) break;
        }
        if (bin_of.size() <= static_cast<std::size_t>(options.max_flat_cells) || quantum >= 256)
            break;
    }
    std::vector<std::array<long long, 4>> cell_sum(bin_of.size(), {0, 0, 0, 0});  // r g b n
    std::vector<int> face_cell(tris.size(), -1);
    const int first_cell = static_cast<int>(items.size());
    for (const int f : flat) {
        const Rgb c = flat_colour[f];
        const int cell = bin_of.at({c.r / quantum, c.g / quantum, c.b / quantum});
        cell_sum[cell][0] += c.r;
        cell_sum[cell][1] += c.g;
        cell_sum[cell][2] += c.b;
        cell_sum[cell][3] += 1;
        face_cell[f] = first_cell + cell;
    }
    for (std::size_t k = 0; k < bin_of.size(); ++k) {
        Item cell;
        cell.width = cell.height = options.flat_cell_px;
        items.push_back(cell);
    }
    RGBD_CHECK(!items.empty(), "texture: nothing to put into the atlas");

    // Scale the charts until they fit into one atlas of at most max_size, else open more.
    double scale = options.scale;
    std::vector<std::size_t> order(items.size());
    std::vector<int> heights;
    int side = 0, atlases = 0;
    for (;;) {
        double area = 0;
        int widest = 0;
        for (auto& it : items) {
            if (it.chart >= 0) {
                const double s = std::min(scale, static_cast<double>(options.max_size) /
                                                     std::max(it.source.width, it.source.height));
                it.width = std::max(1, static_cast<int>(std::ceil(it.source.width * s)));
                it.height = std::max(1, static_cast<int>(std::ceil(it.source.height * s)));
            }
            area += static_cast<double>(it.width) * it.height;
            widest = std::max({widest, it.width, it.height});
        }
        std::iota(order.begin(), order.end(), std::size_t{0});
        std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
            return items[a].height > items[b].height;
        });
        for (side = std::max(64, next_pow2(std::max<double>(widest, std::sqrt(area))));
             side <= options.max_size; side *= 2) {
            atlases = shelf_pack(items, order, side, /*single=*/true, heights);
            if (atlases > 0) break;
        }
        if (atlases > 0) break;
        if (scale <= options.min_scale) {  // several atlases at the lowest scale
            side = options.max_size;
            atlases = shelf_pack(items, order, side, /*single=*/false, heights);
            break;
        }
        scale = std::max(options.min_scale,
                         scale * 0.95 * std::min(0.95, options.max_size / std::sqrt(area)));
    }

    // The atlases: each view's image adjusted once, then each chart's rectangle copied.
    std::vector<cv::Mat> adjusted(views.size());
    for (std::size_t c = 0; c < charts.size(); ++c) {
        const int v = charts[c].view;
        if (adjusted[v].empty()) {
            adjusted[v] = views[v].image.clone();
            apply_gain(adjusted[v], gains[v]);
        }
    }
    for (int a = 0; a < atlases; ++a)
        out.atlases.emplace_back(next_pow2(std::max(heights[a], 1)), side, CV_8UC3,
                                 cv::Scalar(128, 128, 128));
    std::size_t texels = 0;
    for (const auto& it : items) {
        cv::Mat target = out.atlases[it.atlas](cv::Rect(it.x, it.y, it.width, it.height));
        texels += static_cast<std::size_t>(it.width) * it.height;
        if (it.chart < 0) continue;
        const cv::Mat source = adjusted[charts[it.chart].view](it.source);
        if (source.size() == target.size())
            source.copyTo(target);
        else
            cv::resize(source, target, target.size(), 0, 0, cv::INTER_AREA);
        const double sx = static_cast<double>(it.width) / it.source.width;
        const double sy = static_cast<double>(it.height) / it.source.height;
        std::unordered_map<int, Eigen::Vector2d> texel_of;
        for (const auto& [v, p] : corner_px[it.chart])
            texel_of.emplace(v, Eigen::Vector2d((p.x() - it.source.x + 0.5) * sx,
                                                (p.y() - it.source.y + 0.5) * sy));
        std::vector<std::array<int, 3>> faces;
        for (const int f : charts[it.chart].faces) faces.push_back(tris[f]);
        const int reach = static_cast<int>(std::ceil(options.padding_px * sx)) + 2;
        // The chart's seam corrections over its texels (the padding included), then the padding
        // from the chart's own texels.
        if (seams)
            add_chart_correction(target, faces, texel_of, seams->chart_vertex[it.chart], reach);
        if (options.pad_from_chart)
            pad_from_chart(target, chart_mask(target.size(), faces, texel_of), reach);
    }
    // Texture coordinates: a chart corner's image position mapped into its rectangle.
    for (const auto& it : items) {
        if (it.chart < 0) continue;
        const cv::Mat& atlas = out.atlases[it.atlas];
        const double sx = static_cast<double>(it.width) / it.source.width;
        const double sy = static_cast<double>(it.height) / it.source.height;
        std::unordered_map<int, int> uv_of;
        for (const int f : charts[it.chart].faces) {
            out.face_atlas[f] = it.atlas;
            for (int j = 0; j < 3; ++j) {
                const int v = tris[f][j];
                auto [slot, fresh] = uv_of.try_emplace(v, static_cast<int>(out.uvs.size()));
                if (fresh) {
                    const Eigen::Vector2d& p = corner_px[it.chart].at(v);
                    out.uvs.emplace_back(
                        static_cast<float>((it.x + (p.x() - it.source.x + 0.5) * sx) / atlas.cols),
                        static_cast<float>((it.y + (p.y() - it.source.y + 0.5) * sy) / atlas.rows));
                }
                out.face_uvs[f][j] = slot->second;
            }
        }
    }
    // Flat cells: filled with their faces' mean colour; every corner of their faces at the
    // cell's centre.
    std::vector<int> cell_uv(items.size(), -1);
    for (std::size_t k = 0; k < cell_sum.size(); ++k) {
        const int index = first_cell + static_cast<int>(k);
        const Item& it = items[index];
        cv::Mat& atlas = out.atlases[it.atlas];
        const auto& sum = cell_sum[k];
        auto mean = [&](int channel) {
            return static_cast<double>((2 * sum[channel] + sum[3]) / (2 * sum[3]));  // rounded
        };
        atlas(cv::Rect(it.x, it.y, it.width, it.height))
            .setTo(cv::Scalar(mean(2), mean(1), mean(0)));
        cell_uv[index] = static_cast<int>(out.uvs.size());
        out.uvs.emplace_back(static_cast<float>((it.x + 0.5 * it.width) / atlas.cols),
                             static_cast<float>((it.y + 0.5 * it.height) / atlas.rows));
    }
    for (std::size_t f = 0; f < tris.size(); ++f) {
        if (face_cell[f] < 0) continue;
        const int uv = cell_uv[face_cell[f]];
        out.face_uvs[f] = {uv, uv, uv};
        out.face_atlas[f] = items[face_cell[f]].atlas;
    }
    report["charts"] = charts.size();
    report["flat_faces"] = flat_faces;
    report["flat_cells"] = cell_sum.size();
    report["flat_colour_quantum"] = quantum;
    report["atlases"] = atlases;
    Report sizes = Report::array();
    std::size_t total = 0;
    for (const auto& a : out.atlases) {
        sizes.push_back({a.cols, a.rows});
        total += a.total();
    }
    report["atlas_sizes"] = sizes;
    report["texel_scale"] = scale;
    report["atlas_fill"] = total ? static_cast<double>(texels) / total : 0.0;
    return out;
}

}  // namespace rgbd::texture
