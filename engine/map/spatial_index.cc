#include "engine/map/spatial_index.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>

namespace ss {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Cell coordinates beyond this (in cells) are not searched ring by ring: such a query is so far from the map that a
// linear scan is as cheap, and int64 ring arithmetic stays far from overflow.
constexpr double kMaxCellCoord = 1e12;

double dist2(Vec2 a, Vec2 b) {
  double dx = a.x - b.x, dy = a.y - b.y;
  return dx * dx + dy * dy;
}

bool finite(Vec2 p) { return std::isfinite(p.x) && std::isfinite(p.y); }

// (distance squared, index): ordering by this pair is "nearest first, ties by index".
using Candidate = std::pair<double, int>;

// The query's cell (possibly outside the grid) and a lower bound on the distance to anything in ring r.
struct RingQuery {
  int64_t ix = 0, iy = 0;
  double edge = 0;  // distance from the query to the nearest side of its own cell
  int64_t r0 = 0;   // first ring that touches the grid
  int64_t r1 = 0;   // last ring that touches the grid

  // Anything in a cell of ring r >= 1 lies outside the (2r - 1)^2 block of cells around the query's cell. The small
  // slack absorbs rounding in the cell assignment of centres that sit on a cell boundary.
  double inner(int64_t r, double cell) const { return r == 0 ? 0.0 : (r - 1) * cell + edge - 1e-9 * (1 + cell); }
};

// Calls f(first, last) for the order_ range of every grid cell of ring r around (q.ix, q.iy).
template <typename F>
void for_each_ring_cell(const RingQuery& q, int64_t r, int nx, int ny, const std::vector<int>& start, F&& f) {
  auto cell = [&](int64_t x, int64_t y) {
    size_t c = static_cast<size_t>(y * nx + x);
    if (start[c] != start[c + 1]) f(start[c], start[c + 1]);
  };
  auto row = [&](int64_t y) {
    if (y < 0 || y >= ny) return;
    for (int64_t x = std::max<int64_t>(q.ix - r, 0), xe = std::min<int64_t>(q.ix + r, nx - 1); x <= xe; ++x) cell(x, y);
  };
  auto column = [&](int64_t x) {
    if (x < 0 || x >= nx) return;
    for (int64_t y = std::max<int64_t>(q.iy - r + 1, 0), ye = std::min<int64_t>(q.iy + r - 1, ny - 1); y <= ye; ++y)
      cell(x, y);
  };
  if (r == 0) {
    if (q.ix >= 0 && q.ix < nx && q.iy >= 0 && q.iy < ny) cell(q.ix, q.iy);
    return;
  }
  row(q.iy - r);
  row(q.iy + r);
  column(q.ix - r);
  column(q.ix + r);
}

// Sets up a ring search from p; false when p is so far away (or not finite) that a linear scan should be used.
bool ring_query(Vec2 p, double min_x, double min_y, double cell, int nx, int ny, RingQuery& q) {
  double fx = (p.x - min_x) / cell, fy = (p.y - min_y) / cell;
  if (!(std::abs(fx) < kMaxCellCoord && std::abs(fy) < kMaxCellCoord)) return false;
  q.ix = static_cast<int64_t>(std::floor(fx));
  q.iy = static_cast<int64_t>(std::floor(fy));
  auto outside = [](int64_t i, int n) -> int64_t { return i < 0 ? -i : (i >= n ? i - (n - 1) : 0); };
  q.r0 = std::max(outside(q.ix, nx), outside(q.iy, ny));
  // A query further out than the grid is wide would visit about as many rings as a scan visits segments.
  if (q.r0 > static_cast<int64_t>(nx) + ny) return false;
  q.r1 = std::max({q.ix, nx - 1 - q.ix, q.iy, ny - 1 - q.iy});
  double ox = (p.x - min_x) - q.ix * cell, oy = (p.y - min_y) - q.iy * cell;
  q.edge = std::max(0.0, std::min({ox, cell - ox, oy, cell - oy}));
  return true;
}

}  // namespace

SegmentIndex::SegmentIndex(std::span<const MapSegment> segments, double cell_size) {
  const int n = static_cast<int>(segments.size());
  centres_.reserve(n);
  headings_.reserve(n);
  double max_x = -kInf, max_y = -kInf;
  min_x_ = kInf;
  min_y_ = kInf;
  for (const MapSegment& s : segments) {
    centres_.push_back({s.pose.x, s.pose.y});
    headings_.push_back(s.pose.heading);
    if (!finite(centres_.back())) continue;
    min_x_ = std::min(min_x_, s.pose.x);
    min_y_ = std::min(min_y_, s.pose.y);
    max_x = std::max(max_x, s.pose.x);
    max_y = std::max(max_y, s.pose.y);
  }
  cell_ = (std::isfinite(cell_size) && cell_size > 0) ? cell_size : 10.0;
  if (!(min_x_ <= max_x)) {  // no segment with a finite centre: an empty grid
    min_x_ = min_y_ = 0;
    nx_ = ny_ = 0;
    cell_start_.assign(1, 0);
    return;
  }
  // Bound the cell count by the segment count so a sparse map spread over many km (or a tiny cell size) cannot
  // allocate an enormous grid; coarser cells only make queries scan a few more segments.
  const double ex = max_x - min_x_, ey = max_y - min_y_;
  const double max_cells = std::max(1024.0, 4.0 * n);
  if (std::isfinite(ex) && std::isfinite(ey)) {
    cell_ = std::max({cell_, std::sqrt(ex * ey / max_cells), std::max(ex, ey) / max_cells});
    while ((std::floor(ex / cell_) + 1) * (std::floor(ey / cell_) + 1) > max_cells) cell_ *= 1.5;
    nx_ = static_cast<int>(std::floor(ex / cell_)) + 1;
    ny_ = static_cast<int>(std::floor(ey / cell_)) + 1;
  } else {  // centres spread beyond the double range: one cell, every query a scan
    cell_ = std::numeric_limits<double>::max();
    nx_ = ny_ = 1;
  }

  // CSR cell lists by counting sort; segments keep index order inside a cell.
  std::vector<int> cell_of(n, -1);
  cell_start_.assign(static_cast<size_t>(nx_) * ny_ + 1, 0);
  for (int i = 0; i < n; ++i) {
    if (!finite(centres_[i])) continue;  // never returned: no distance to compare
    // Clamped in double before the conversion: (x - min) / cell is >= 0 but may round past the last cell.
    int cx = static_cast<int>(std::min((centres_[i].x - min_x_) / cell_, nx_ - 1.0));
    int cy = static_cast<int>(std::min((centres_[i].y - min_y_) / cell_, ny_ - 1.0));
    cell_of[i] = cy * nx_ + cx;
    ++cell_start_[cell_of[i] + 1];
  }
  for (size_t c = 1; c < cell_start_.size(); ++c) cell_start_[c] += cell_start_[c - 1];
  order_.resize(cell_start_.back());
  std::vector<int> fill(cell_start_.begin(), cell_start_.end() - 1);
  for (int i = 0; i < n; ++i)
    if (cell_of[i] >= 0) order_[fill[cell_of[i]]++] = i;
}

int SegmentIndex::nearest(const Pose& pose, double max_heading_diff) const {
  const Vec2 p{pose.x, pose.y};
  // wrap_angle maps into [-pi, pi), so an exactly opposite segment differs by pi: "pi or more" must skip the test
  // rather than compare |-pi| < pi.
  const bool filter = max_heading_diff < kPi;
  if (!finite(p)) return -1;
  double best = kInf;
  int best_i = -1;
  auto consider = [&](int i) {
    double d = dist2(p, centres_[i]);
    if (!(d <= best) || (d == best && i > best_i)) return;
    if (filter && !(std::abs(wrap_angle(headings_[i] - pose.heading)) < max_heading_diff)) return;
    best = d;
    best_i = i;
  };
  RingQuery q;
  if (nx_ == 0 || !ring_query(p, min_x_, min_y_, cell_, nx_, ny_, q)) {
    for (int i : order_) consider(i);
    return best_i;
  }
  for (int64_t r = q.r0; r <= q.r1; ++r) {
    double inner = q.inner(r, cell_);
    if (inner > 0 && inner * inner > best) break;
    for_each_ring_cell(q, r, nx_, ny_, cell_start_, [&](int a, int b) {
      for (int k = a; k < b; ++k) consider(order_[k]);
    });
  }
  return best_i;
}

std::vector<int> SegmentIndex::within_radius(Vec2 p, double radius) const {
  std::vector<int> out;
  if (nx_ == 0 || !finite(p) || !(radius >= 0)) return out;
  const double r2 = radius * radius;
  std::vector<Candidate> found;
  // The cells overlapping the circle's bounding box, clamped to the grid in double before any integer conversion.
  auto range = [&](double lo, double hi, double origin, int n, int64_t& a, int64_t& b) {
    double fa = std::floor((lo - origin) / cell_), fb = std::floor((hi - origin) / cell_);
    a = static_cast<int64_t>(std::clamp(fa, 0.0, n - 1.0));
    b = static_cast<int64_t>(std::clamp(fb, 0.0, n - 1.0));
    return fb >= 0 && fa <= n - 1;
  };
  int64_t x0, x1, y0, y1;
  if (!range(p.x - radius, p.x + radius, min_x_, nx_, x0, x1) || !range(p.y - radius, p.y + radius, min_y_, ny_, y0, y1))
    return out;
  for (int64_t y = y0; y <= y1; ++y) {
    for (int64_t x = x0; x <= x1; ++x) {
      size_t c = static_cast<size_t>(y * nx_ + x);
      for (int k = cell_start_[c]; k < cell_start_[c + 1]; ++k) {
        int i = order_[k];
        double d = dist2(p, centres_[i]);
        if (d <= r2) found.push_back({d, i});
      }
    }
  }
  std::sort(found.begin(), found.end());
  out.reserve(found.size());
  for (const Candidate& c : found) out.push_back(c.second);
  return out;
}

std::vector<int> SegmentIndex::k_nearest(Vec2 p, int k) const { return nearest(p, k, true); }

std::vector<int> SegmentIndex::k_nearest_unordered(Vec2 p, int k) const { return nearest(p, k, false); }

std::vector<int> SegmentIndex::nearest(Vec2 p, int k, bool sorted) const {
  std::vector<int> out;
  if (k <= 0 || nx_ == 0 || !finite(p)) return out;
  const int n = static_cast<int>(order_.size());
  RingQuery q;
  std::vector<Candidate> found;
  if (k >= n || !ring_query(p, min_x_, min_y_, cell_, nx_, ny_, q)) {
    // Everything (or a far query): every segment, cut to the k nearest.
    found.reserve(n);
    for (int i : order_) found.push_back({dist2(p, centres_[i]), i});
    if (static_cast<int>(found.size()) > k) {
      std::nth_element(found.begin(), found.begin() + (k - 1), found.end());
      found.resize(k);
    }
  } else {
    // Gather ring by ring; once k are known, the k-th best distance bounds the search and the rest is dropped.
    for (int64_t r = q.r0; r <= q.r1; ++r) {
      if (static_cast<int>(found.size()) >= k) {
        std::nth_element(found.begin(), found.begin() + (k - 1), found.end());
        found.resize(k);
        double inner = q.inner(r, cell_);
        if (inner > 0 && inner * inner > found[k - 1].first) break;
      }
      for_each_ring_cell(q, r, nx_, ny_, cell_start_, [&](int a, int b) {
        for (int j = a; j < b; ++j) found.push_back({dist2(p, centres_[order_[j]]), order_[j]});
      });
    }
    if (static_cast<int>(found.size()) > k) {
      std::nth_element(found.begin(), found.begin() + (k - 1), found.end());
      found.resize(k);
    }
  }
  if (sorted) std::sort(found.begin(), found.end());
  out.reserve(found.size());
  for (const Candidate& c : found) out.push_back(c.second);
  return out;
}

size_t SegmentIndex::bytes() const {
  return centres_.capacity() * sizeof(Vec2) + headings_.capacity() * sizeof(double) +
         (cell_start_.capacity() + order_.capacity()) * sizeof(int);
}

}  // namespace ss
