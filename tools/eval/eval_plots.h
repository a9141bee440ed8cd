// `eval --plots DIR`: one SVG per continuous WOSAC feature, the log's and the rollouts' value distributions as
// overlaid histograms (each normalised to its own total), over the feature's WOSAC range.
#pragma once

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "offline/eval/aggregate.h"

namespace ss::cli {

// One histogram as an SVG document; `title` names the feature, `label` the rollouts.
std::string histogram_svg(const std::string& title, const std::string& label, double min, double max,
                          const std::vector<double>& log, const std::vector<double>& sim);

// Writes DIR/<feature>.svg for each continuous feature (creating DIR); returns the files written.
absl::Status write_feature_plots(const std::string& dir, const std::string& label, const DatasetEvaluation& d,
                                 std::vector<std::string>* written);

}  // namespace ss::cli
