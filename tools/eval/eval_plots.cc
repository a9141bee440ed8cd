#include "tools/eval/eval_plots.h"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "offline/render/svg_text.h"

namespace ss::cli {
namespace {

constexpr double kWidth = 640, kHeight = 360, kLeft = 56, kRight = 16, kTop = 40, kBottom = 48;

std::vector<double> normalised(const std::vector<double>& counts) {
  double total = 0;
  for (double c : counts) total += c;
  std::vector<double> out(counts.size(), 0.0);
  if (total > 0)
    for (size_t i = 0; i < counts.size(); ++i) out[i] = counts[i] / total;
  return out;
}

const char* unit(RealismFeature f) {
  switch (f) {
    case kLinearSpeed: return "m/s";
    case kLinearAcceleration: return "m/s^2";
    case kAngularSpeed: return "rad/s";
    case kAngularAcceleration: return "rad/s^2";
    case kTimeToCollision: return "s";
    default: return "m";
  }
}

}  // namespace

std::string histogram_svg(const std::string& title, const std::string& label, double min, double max,
                          const std::vector<double>& log, const std::vector<double>& sim) {
  const std::vector<double> a = normalised(log), b = normalised(sim);
  const size_t bins = std::max(a.size(), b.size());
  double top = 0;
  for (double v : a) top = std::max(top, v);
  for (double v : b) top = std::max(top, v);
  if (top <= 0) top = 1;
  const double plot_w = kWidth - kLeft - kRight, plot_h = kHeight - kTop - kBottom;
  const double bar = bins ? plot_w / bins : plot_w;
  SvgWriter s(kWidth, kHeight, 12);
  s.text(kLeft, 22, title, "font-size=\"15\"");
  // Bars: the log filled, the rollouts outlined on top, so both stay visible where they overlap.
  for (size_t i = 0; i < bins; ++i) {
    const double x = kLeft + i * bar;
    const double ha = i < a.size() ? a[i] / top * plot_h : 0, hb = i < b.size() ? b[i] / top * plot_h : 0;
    s.rect(x + 1, kTop + plot_h - ha, bar - 2, ha, "fill=\"#9ecae1\"");
    s.rect(x + 1, kTop + plot_h - hb, bar - 2, hb, "fill=\"none\" stroke=\"#d62728\" stroke-width=\"1.5\"");
  }
  // Axes with the range ends and the middle, and the largest share.
  s.line(kLeft, kTop + plot_h, kLeft + plot_w, kTop + plot_h, "stroke=\"black\"");
  s.line(kLeft, kTop, kLeft, kTop + plot_h, "stroke=\"black\"");
  for (int k = 0; k <= 2; ++k)
    s.text(kLeft + k * plot_w / 2, kTop + plot_h + 16, absl::StrFormat("%g", min + k * (max - min) / 2),
           "text-anchor=\"middle\"");
  s.text(kLeft - 4, kTop + 4, absl::StrFormat("%.2f", top), "text-anchor=\"end\"");
  s.text(kLeft - 4, kTop + plot_h, "0", "text-anchor=\"end\"");
  s.rect(kLeft, kHeight - 18, 12, 10, "fill=\"#9ecae1\"").text(kLeft + 16, kHeight - 9, "log");
  s.rect(kLeft + 70, kHeight - 18, 12, 10, "fill=\"none\" stroke=\"#d62728\"").text(kLeft + 86, kHeight - 9, label);
  return s.finish();
}

absl::Status write_feature_plots(const std::string& dir, const std::string& label, const DatasetEvaluation& d,
                                 std::vector<std::string>* written) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return absl::PermissionDeniedError(absl::StrCat("--plots: cannot create ", dir, ": ", ec.message()));
  for (int f = 0; f < kNumRealismFeatures; ++f) {
    const FeatureConfig& c = wosac_2025_config()[f];
    const FeatureHistogram& h = d.histograms[f];
    if (c.bernoulli || h.log.empty()) continue;
    const std::string path = (std::filesystem::path(dir) / (std::string(c.name) + ".svg")).string();
    const std::string svg = histogram_svg(absl::StrCat(c.name, " (", unit(static_cast<RealismFeature>(f)),
                                                       "): log vs rollouts, share of scored frames"),
                                          label,
                                          c.histogram.min, c.histogram.max, h.log, h.sim);
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out << svg;
    out.close();
    if (!out) return absl::PermissionDeniedError(absl::StrCat("--plots: cannot write ", path, ": ", std::strerror(errno)));
    written->push_back(path);
  }
  return absl::OkStatus();
}

}  // namespace ss::cli
