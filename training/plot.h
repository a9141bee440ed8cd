// Loss curves of a run as one SVG: a panel per head, train loss (a line) and val loss (dots) against the step,
// read from the run's train_log.csv and val_log.csv.
#pragma once

#include <string>

#include "absl/status/status.h"

namespace ss::train {

absl::Status plot_run(const std::string& run_dir, const std::string& svg_path);

}  // namespace ss::train
