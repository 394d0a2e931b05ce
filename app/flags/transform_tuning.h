#pragma once
// The residual transform's tuning on a command line: `odvr light` and `odvr bench light` take the
// same flags, checked alike, written straight into the options the transform is built with.
#include <CLI/CLI.hpp>

#include "engine/lighting/residual_transform.h"

namespace odvr::app {

// --sweeps, --fine-sweeps, --fine-relaxation, --base-width, --region-cutoff,
// --broad-region-cutoff, --keep-threshold, --normalization, --exact-reconstruction/--magnify and
// --no-coarse-correction, each into its field of `options` (which must outlive the parse), the
// field's value as the default.
void AddTransformTuning(CLI::App* sub, lighting::ResidualTransformOptions* options);

}  // namespace odvr::app
