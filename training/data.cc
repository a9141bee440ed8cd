#include "training/data.h"

#include <algorithm>
#include <numeric>

#include "absl/strings/str_cat.h"
#include "engine/scenario/read.h"
#include "engine/base/rng.h"

namespace ss::train {

absl::StatusOr<Corpus> load_corpus(const std::vector<std::string>& paths) {
  Corpus c;
  for (const std::string& path : paths) {
    auto files = list_scenario_files(path, true);
    if (!files.ok()) return files.status();
    for (const std::string& f : *files) {
      auto n = for_each_scenario(f, [&](Scenario&& s) {
        c.scenarios.push_back(std::move(s));
        return absl::OkStatus();
      });
      if (!n.ok()) return n.status();
      c.files.push_back(f);
    }
  }
  return c;
}

SampleOrder::SampleOrder(int real_scenarios, int synthetic_scenarios, double real_fraction, uint64_t seed)
    : real_(real_scenarios), synthetic_(synthetic_scenarios), real_fraction_(real_fraction), seed_(seed) {}

SampleRef SampleOrder::at(int source, int64_t position) const {
  const int n = (source == 0 ? real_ : synthetic_) * kPhases;
  const int64_t epoch = position / n;
  std::vector<int> perm(n);
  std::iota(perm.begin(), perm.end(), 0);
  Rng rng(mix_seed(seed_ ^ mix_seed(static_cast<uint64_t>(epoch) * 2 + source)));
  for (int i = n - 1; i > 0; --i) std::swap(perm[i], perm[rng.next() % (i + 1)]);
  const int item = perm[position % n];
  return {source, item / kPhases, item % kPhases};
}

SampleRef SampleOrder::next(DataCursor& c) const {
  const double u = static_cast<double>(mix_seed(seed_ * 31 + static_cast<uint64_t>(c.samples)) >> 11) * 0x1.0p-53;
  const bool real = synthetic_ == 0 || (real_ > 0 && u < real_fraction_);
  ++c.samples;
  return real ? at(0, c.real++) : at(1, c.synthetic++);
}

uint64_t SampleOrder::sample_seed(int64_t sample) const { return mix_seed(seed_ + 0x5151 + static_cast<uint64_t>(sample)) | 1; }

}  // namespace ss::train
