#include "training/plot.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "engine/io/file_io.h"

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
  std::ostringstream svg;
  svg << absl::StrFormat("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%d\" height=\"%d\" font-family=\"sans-serif\" font-size=\"11\">\n",
                         cols * w, 2 * h + 24);
  svg << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  svg << absl::StrFormat("<text x=\"8\" y=\"16\" font-size=\"13\">Loss per head (cross-entropy) against the step: "
                         "train (blue line, mean of each logged window), val (orange dots). Steps 0-%.0f.</text>\n", max_step);
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
    svg << absl::StrFormat("<text x=\"%d\" y=\"%d\">%s</text>\n", x0, y0 - 6, titles[p]);
    svg << absl::StrFormat("<rect x=\"%d\" y=\"%d\" width=\"%d\" height=\"%d\" fill=\"none\" stroke=\"#999\"/>\n", x0, y0, pw, ph);
    if (!(hi > lo)) hi = lo + 1;
    if (!std::isfinite(lo)) lo = 0, hi = 1;
    auto X = [&](double s) { return x0 + pw * s / std::max(1.0, max_step); };
    auto Y = [&](double v) { return y0 + ph * (1 - (v - lo) / (hi - lo)); };
    for (int k = 0; k <= 4; ++k) {
      const double v = lo + (hi - lo) * k / 4;
      svg << absl::StrFormat("<text x=\"%d\" y=\"%.1f\" text-anchor=\"end\">%.2f</text>\n", x0 - 4, Y(v) + 4, v);
    }
    svg << absl::StrFormat("<text x=\"%d\" y=\"%d\">0</text><text x=\"%d\" y=\"%d\" text-anchor=\"end\">%.0f</text>\n",
                           x0, y0 + ph + 14, x0 + pw, y0 + ph + 14, max_step);
    std::string path;
    for (const auto& [step, row] : *train)
      if (auto it = row.find(col); it != row.end() && it->second > 0)
        absl::StrAppendFormat(&path, "%s%.1f,%.1f ", path.empty() ? "M" : "L", X(step), Y(it->second));
    svg << absl::StrFormat("<path d=\"%s\" fill=\"none\" stroke=\"#1f77b4\" stroke-width=\"1.2\"/>\n", path);
    for (const auto& [step, row] : *val)
      if (auto it = row.find(col); it != row.end() && it->second > 0)
        svg << absl::StrFormat("<circle cx=\"%.1f\" cy=\"%.1f\" r=\"2.5\" fill=\"#ff7f0e\"/>\n", X(step), Y(it->second));
  }
  svg << "</svg>\n";
  return file_write_atomically(svg_path, svg.str());
}

}  // namespace ss::train
