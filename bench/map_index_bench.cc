// Map segmentation, SegmentIndex queries and road-edge distances on the real 301-feature WOMD map. Each benchmark
// iteration runs the whole batch of 10^5 queries, so the reported time is the time for 10^5 queries; the brute-force
// nearest runs the same queries so the speed-up is visible in one run.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "engine/map/road_edges.h"
#include "engine/map/segments.h"
#include "engine/map/spatial_index.h"
#include "engine/scenario/read.h"
#include "engine/sim/events.h"

namespace ss {
namespace {

constexpr int kQueries = 100000;

struct Fixture {
  bool ok = false;
  std::string error;
  Scenario scenario;
  std::vector<MapSegment> segments;
  std::vector<Pose> queries;
  std::vector<Pose> near_lanes;  // lane points moved up to 3 m: where agents' corners are (reject sampling asks these)
};

const Fixture& fixture() {
  static const Fixture f = [] {
    Fixture f;
    auto read = read_scenarios(std::string(SS_DATA_DIR) + "/womd/tfrecord/motion_data_one_scenario.tfrecord");
    if (!read.ok() || read->empty()) {
      f.error = read.ok() ? "no scenario in the file" : std::string(read.status().message());
      return f;
    }
    f.scenario = std::move(read->front());
    f.segments = segment_map(f.scenario);
    double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
    for (const MapFeature& m : f.scenario.map_features) {
      for (const MapPoint& p : m.points) {
        x0 = std::min(x0, p.x), x1 = std::max(x1, p.x);
        y0 = std::min(y0, p.y), y1 = std::max(y1, p.y);
      }
    }
    std::mt19937_64 rng(20240601);  // fixed: every run asks the same queries
    std::uniform_real_distribution<double> ux(x0, x1), uy(y0, y1), uh(-kPi, kPi);
    f.queries.reserve(kQueries);
    for (int i = 0; i < kQueries; ++i) f.queries.push_back({ux(rng), uy(rng), uh(rng)});
    std::vector<MapPoint> lane_points;
    for (const MapFeature& m : f.scenario.map_features)
      if (m.kind == MapFeatureKind::lane) lane_points.insert(lane_points.end(), m.points.begin(), m.points.end());
    std::uniform_int_distribution<size_t> pick(0, lane_points.size() - 1);
    std::uniform_real_distribution<double> jitter(-3.0, 3.0);
    for (int i = 0; i < kQueries && !lane_points.empty(); ++i) {
      const MapPoint& p = lane_points[pick(rng)];
      f.near_lanes.push_back({p.x + jitter(rng), p.y + jitter(rng), 0});
    }
    std::fprintf(stderr, "map: %zu features -> %zu segments, bounding box %.0f x %.0f m\n",
                 f.scenario.map_features.size(), f.segments.size(), x1 - x0, y1 - y0);
    f.ok = true;
    return f;
  }();
  return f;
}

bool ready(benchmark::State& state) {
  if (fixture().ok) return true;
  state.SkipWithError(("cannot read the real map: " + fixture().error).c_str());
  return false;
}

void BM_SegmentMap(benchmark::State& state) {
  if (!ready(state)) return;
  for (auto _ : state) benchmark::DoNotOptimize(segment_map(fixture().scenario));
  state.counters["segments"] = static_cast<double>(fixture().segments.size());
}

void BM_IndexBuild(benchmark::State& state) {
  if (!ready(state)) return;
  for (auto _ : state) {
    SegmentIndex index(fixture().segments);
    benchmark::DoNotOptimize(index);
  }
}

void BM_Nearest(benchmark::State& state) {
  if (!ready(state)) return;
  const SegmentIndex index(fixture().segments);
  for (auto _ : state) {
    long sum = 0;
    for (const Pose& q : fixture().queries) sum += index.nearest(q, kPi / 2);
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * kQueries);
}

// The linear scan the index replaces (same filter, same tie rule).
int brute_nearest(const std::vector<MapSegment>& segs, const Pose& q) {
  int best = -1;
  double best_d = std::numeric_limits<double>::infinity();
  for (int i = 0; i < static_cast<int>(segs.size()); ++i) {
    double dx = q.x - segs[i].pose.x, dy = q.y - segs[i].pose.y, d = dx * dx + dy * dy;
    if (d < best_d && std::abs(wrap_angle(segs[i].pose.heading - q.heading)) < kPi / 2) best_d = d, best = i;
  }
  return best;
}

void BM_NearestBruteForce(benchmark::State& state) {
  if (!ready(state)) return;
  const auto& segs = fixture().segments;
  // Checked before the timed loop: the index must agree with the scan on every query.
  const SegmentIndex index(segs);
  long mismatches = 0;
  for (const Pose& q : fixture().queries) mismatches += brute_nearest(segs, q) != index.nearest(q, kPi / 2);
  for (auto _ : state) {
    long sum = 0;
    for (const Pose& q : fixture().queries) sum += brute_nearest(segs, q);
    benchmark::DoNotOptimize(sum);
  }
  state.counters["mismatches"] = static_cast<double>(mismatches);
  state.SetItemsProcessed(state.iterations() * kQueries);
}

void BM_WithinRadius50(benchmark::State& state) {
  if (!ready(state)) return;
  const SegmentIndex index(fixture().segments);
  double found = 0;
  for (auto _ : state) {
    size_t n = 0;
    for (const Pose& q : fixture().queries) n += index.within_radius({q.x, q.y}, 50.0).size();
    benchmark::DoNotOptimize(n);
    found = static_cast<double>(n) / kQueries;
  }
  state.counters["mean_found"] = found;
  state.SetItemsProcessed(state.iterations() * kQueries);
}

void BM_KNearest128(benchmark::State& state) {
  if (!ready(state)) return;
  const SegmentIndex index(fixture().segments);
  for (auto _ : state) {
    size_t n = 0;
    for (const Pose& q : fixture().queries) n += index.k_nearest({q.x, q.y}, 128).size();
    benchmark::DoNotOptimize(n);
  }
  state.SetItemsProcessed(state.iterations() * kQueries);
}

// Signed distances to the road edge (RoadEdges' grid) as a session asks them (edges flattened to the plane), at
// points near lanes and anywhere on the map.
void road_edge_distances(benchmark::State& state, const std::vector<Pose>& queries) {
  if (!ready(state)) return;
  const RoadEdges edges = event_map_from_scenario(fixture().scenario).edges;
  for (auto _ : state) {
    double sum = 0;
    for (const Pose& q : queries) sum += edges.signed_distance(q.x, q.y, 0);
    benchmark::DoNotOptimize(sum);
  }
  state.counters["grid_kB"] = static_cast<double>(edges.bytes()) / 1024;
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(queries.size()));
}
void BM_RoadEdgeNearLanes(benchmark::State& state) { road_edge_distances(state, fixture().near_lanes); }
void BM_RoadEdgeAnywhere(benchmark::State& state) { road_edge_distances(state, fixture().queries); }

BENCHMARK(BM_SegmentMap)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_IndexBuild)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Nearest)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_NearestBruteForce)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_WithinRadius50)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_KNearest128)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RoadEdgeNearLanes)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RoadEdgeAnywhere)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace ss

BENCHMARK_MAIN();
