#include "training/plot.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "engine/io/file_io.h"
#include "offline/render/svg_text.h"

namespace ss::train {
namespace {

// step -> column -> value; a step logged twice (a run resumed from an earlier checkpoint) keeps its last line.
using Table = std::map<double, std::map<std::string, double>>;

absl::StatusOr<Table> read_csv(const std::string& path, bool required) {
  std::ifstream f(path);
  Table t;
  if (!f) {
    if (required) return absl::NotFoundError(absl::StrCat(path, ": cannot be opened"));
    return t;
  }
  std::string line;
  std::getline(f, line);
  const std::vector<std::string> header = absl::StrSplit(line, ',');
  for (int n = 2; std::getline(f, line); ++n) {
    const std::vector<std::string> cells = absl::StrSplit(line, ',');
    if (cells.size() != header.size())
      return absl::InvalidArgumentError(absl::StrCat(path, ":", n, ": ", cells.size(), " cells, the header has ", header.size()));
    std::map<std::string, double> row;
    for (size_t i = 0; i < cells.size(); ++i)
      if (!absl::SimpleAtod(cells[i], &row[header[i]]))
        return absl::InvalidArgumentError(absl::StrCat(path, ":", n, ": '", cells[i], "' is not a number"));
    t[row["step"]] = row;
  }
  return t;
}

}  // namespace

absl::Status plot_run(const std::string& run_dir, const std::string& svg_path) {
  auto train = read_csv(run_dir + "/train_log.csv", true);
  if (!train.ok()) return train.status();
  auto val = read_csv(run_dir + "/val_log.csv", false);
  if (!val.ok()) return val.status();
  if (train->empty()) return absl::InvalidArgumentError(run_dir + "/train_log.csv has no rows");
  const char* heads[] = {"motion", "light", "type", "end", "segment", "state"};
  const char* titles[] = {"motion (1089 controls)", "light (next state)", "agent type (at SOA)",
                          "end of agents (at SOS, RS)", "map segment pointer (at TYPE)", "relative state (8 fields)"};
  const int w = 340, h = 220, pad = 44, cols = 3;
  const double max_step = train->rbegin()->first;
  SvgWriter svg(cols * w, 2 * h + 24, 11);
  svg.text(8, 16, absl::StrFormat("Loss per head (cross-entropy) against the step: train (blue line, mean of each "
                                  "logged window), val (orange dots). Steps 0-%.0f.", max_step),
           "font-size=\"13\"");
  for (int p = 0; p < 6; ++p) {
    const std::string col = absl::StrCat(heads[p], "_loss");
    const int x0 = (p % cols) * w + pad, y0 = 24 + (p / cols) * h + 18, pw = w - pad - 12, ph = h - 58;
    double lo = INFINITY, hi = -INFINITY;
    auto scan = [&](const Table& t) {
      for (const auto& [step, row] : t)
        if (auto it = row.find(col); it != row.end() && it->second > 0) lo = std::min(lo, it->second), hi = std::max(hi, it->second);
    };
    scan(*train);
    scan(*val);
    svg.text(x0, y0 - 6, titles[p]);
    svg.rect(x0, y0, pw, ph, "fill=\"none\" stroke=\"#999\"");
    if (!(hi > lo)) hi = lo + 1;
    if (!std::isfinite(lo)) lo = 0, hi = 1;
    auto X = [&](double s) { return x0 + pw * s / std::max(1.0, max_step); };
    auto Y = [&](double v) { return y0 + ph * (1 - (v - lo) / (hi - lo)); };
    for (int k = 0; k <= 4; ++k) {
      const double v = lo + (hi - lo) * k / 4;
      svg.text(x0 - 4, Y(v) + 4, absl::StrFormat("%.2f", v), "text-anchor=\"end\"");
    }
    svg.text(x0, y0 + ph + 14, "0");
    svg.text(x0 + pw, y0 + ph + 14, absl::StrFormat("%.0f", max_step), "text-anchor=\"end\"");
    std::vector<Vec2> line;
    for (const auto& [step, row] : *train)
      if (auto it = row.find(col); it != row.end() && it->second > 0) line.push_back({X(step), Y(it->second)});
    svg.path(line, "fill=\"none\" stroke=\"#1f77b4\" stroke-width=\"1.2\"");
    for (const auto& [step, row] : *val)
      if (auto it = row.find(col); it != row.end() && it->second > 0)
        svg.circle(X(step), Y(it->second), 2.5, "fill=\"#ff7f0e\"");
  }
  return file_write_atomically(svg_path, svg.finish());
}

}  // namespace ss::train
