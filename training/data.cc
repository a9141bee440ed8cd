#include "training/data.h"

#include <algorithm>
#include <numeric>

#include "absl/strings/str_cat.h"
#include "engine/scenario/read.h"
#include "engine/sim/rng.h"

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

namespace {

// splitmix64: a seed mixer, so nearby (seed, index) pairs give unrelated values.
uint64_t mix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

}  // namespace

SampleOrder::SampleOrder(int real_scenarios, int synthetic_scenarios, double real_fraction, uint64_t seed)
    : real_(real_scenarios), synthetic_(synthetic_scenarios), real_fraction_(real_fraction), seed_(seed) {}

SampleRef SampleOrder::at(int source, int64_t position) const {
  const int n = (source == 0 ? real_ : synthetic_) * kPhases;
  const int64_t epoch = position / n;
  std::vector<int> perm(n);
  std::iota(perm.begin(), perm.end(), 0);
  Rng rng(mix(seed_ ^ mix(static_cast<uint64_t>(epoch) * 2 + source)));
  for (int i = n - 1; i > 0; --i) std::swap(perm[i], perm[rng.next() % (i + 1)]);
  const int item = perm[position % n];
  return {source, item / kPhases, item % kPhases};
}

SampleRef SampleOrder::next(DataCursor& c) const {
  const double u = static_cast<double>(mix(seed_ * 31 + static_cast<uint64_t>(c.samples)) >> 11) * 0x1.0p-53;
  const bool real = synthetic_ == 0 || (real_ > 0 && u < real_fraction_);
  ++c.samples;
  return real ? at(0, c.real++) : at(1, c.synthetic++);
}

uint64_t SampleOrder::sample_seed(int64_t sample) const { return mix(seed_ + 0x5151 + static_cast<uint64_t>(sample)) | 1; }

}  // namespace ss::train
