// The software rasteriser moved to algorithms/render/rasterizer.hpp so that rgbd-render can use
// it; rgbd-synth keeps its names.
#pragma once

#include "algorithms/render/rasterizer.hpp"

namespace rgbd::synth {

using render::DepthRender;
using render::RasterOptions;
using render::render_color;
using render::render_depth;
using render::RenderScene;
using render::Shader;

}  // namespace rgbd::synth
