#include "app/flags/transform_tuning.h"

#include <string>

#include "app/flags/command_flags.h"

namespace odvr::app {

void AddTransformTuning(CLI::App* sub, lighting::ResidualTransformOptions* options) {
  sub->add_option("--sweeps", options->sweeps,
                  "Projection passes per level of λ < 300, levels 0-2 (1: the seed's; more: closer to least squares)")
      ->check(CLI::Range(1, 16))
      ->capture_default_str();
  sub->add_option("--fine-sweeps", options->fine_sweeps, "Projection passes per level of λ >= 300, levels 3-5")
      ->check(CLI::Range(1, 16))
      ->capture_default_str();
  sub->add_option("--fine-relaxation", options->fine_relaxation,
                  "Step of the refitting passes at levels 3-5 (1: plain; above 1 over-relaxes them)")
      ->check(CLI::Range(0.05, 1.95))
      ->capture_default_str();
  sub->add_option("--base-width", options->base_width, "Working-grid width of level 0, doubling per level")
      ->check(CLI::Range(8, 4096))
      ->capture_default_str();
  sub->add_option("--region-cutoff", options->region_cutoff,
                  "An SRBF's cap: where its Gaussian exceeds this (levels 3-5)")
      ->check(CLI::Range(1e-9, 0.4))
      ->capture_default_str();
  sub->add_option("--broad-region-cutoff", options->broad_region_cutoff, "The cap's cut-off of the levels 0-2")
      ->check(CLI::Range(1e-9, 0.4))
      ->capture_default_str();
  sub->add_option("--keep-threshold", options->keep_threshold,
                  "Drop SRBFs whose largest |amplitude| is under this times the mean radiance")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  sub->add_option_function<std::string>(
         "--normalization",
         [options](const std::string& name) {
           options->normalization = name == "none"        ? lighting::Normalization::kNone
                                    : name == "local-sum" ? lighting::Normalization::kLocalSum
                                                          : lighting::Normalization::kPartition;
         },
         "Amplitude normalization of the transform (default partition)")
      ->check(CLI::IsMember({"none", "local-sum", "partition"}));
  AddSetFlag(sub, "--exact-reconstruction", &options->exact_reconstruction, true,
             "Evaluate every coarser level on each level's grid");
  AddSetFlag(sub, "--magnify", &options->exact_reconstruction, false,
             "Magnify the coarser grid's reconstruction through six samples per axis (the default: as accurate, "
             "faster)");
  AddSetFlag(sub, "--no-coarse-correction", &options->coarse_correction, false,
             "Do not let the two levels below the finest refit what every level left");
}

}  // namespace odvr::app
