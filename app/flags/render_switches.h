#pragma once
// The renderer's switches that `odvr render` and `odvr bench render` both take (the lighting
// lists, the ground's lit-fraction grid, the peaks' shadows, the reflection normals, the specular
// bounce, the shading rate), declared once and bound straight to a RenderOptions, so the two
// commands cannot drift apart in a flag's name, range or meaning.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "engine/render/triple_product_renderer.h"

namespace odvr::app {

// Declares the switches on `sub`; `options` must outlive the parse.
void AddRenderSwitches(CLI::App* sub, render::RenderOptions* options);

// The switches `options` sets away from RenderOptions' defaults, each as the command line that
// sets it ("--bin-depth", "--shading-rate 2"), in the order AddRenderSwitches declares them.
std::vector<std::string> NonDefaultRenderSwitches(const render::RenderOptions& options);

// Every switch's value under its RenderOptions name ("depth_per_lobe", "overlap_cutoff", ...).
nlohmann::json RenderSwitchesJson(const render::RenderOptions& options);

}  // namespace odvr::app
