#include "offline/dataset/sumo_events.h"

#include <algorithm>
#include <charconv>

#include "offline/dataset/xml_scan.h"

namespace ss {

void SignalTimeline::add(const std::string& tl, double time, std::string state) {
  auto& v = switches_[tl];
  Switch s{time, std::move(state)};
  // Outputs are in time order; keep the timeline sorted even if one is not.
  auto at = std::upper_bound(v.begin(), v.end(), time, [](double t, const Switch& w) { return t < w.time; });
  v.insert(at, std::move(s));
}

const std::string* SignalTimeline::state_at(const std::string& tl, double t) const {
  auto it = switches_.find(tl);
  if (it == switches_.end()) return nullptr;
  const auto& v = it->second;
  // A switch logged at t counts from t on; the tolerance absorbs the float time of 0.1 s steps.
  auto after = std::upper_bound(v.begin(), v.end(), t + 1e-6, [](double x, const Switch& w) { return x < w.time; });
  if (after == v.begin()) return nullptr;
  return &std::prev(after)->state;
}

absl::StatusOr<SignalTimeline> parse_signal_switches(std::string_view xml, const std::string& where) {
  SignalTimeline timeline;
  XmlScanner x(xml, where);
  while (true) {
    auto more = x.next();
    if (!more.ok()) return more.status();
    if (!*more) break;
    if (!x.is_start() || x.name() != "tlsState") continue;
    auto t = x.number("time");
    if (!t.ok()) return t.status();
    timeline.add(x.get("id"), *t, x.get("state"));
  }
  return timeline;
}

absl::StatusOr<std::vector<Incident>> parse_collisions(std::string_view xml, const std::string& where) {
  std::vector<Incident> out;
  XmlScanner x(xml, where);
  while (true) {
    auto more = x.next();
    if (!more.ok()) return more.status();
    if (!*more) break;
    if (!x.is_start() || x.name() != "collision") continue;
    auto t = x.number("time");
    if (!t.ok()) return t.status();
    for (const char* who : {"collider", "victim"})
      if (x.has(who)) out.push_back({x.get(who), *t, false});
  }
  return out;
}

std::vector<Incident> parse_teleports(std::string_view log) {
  std::vector<Incident> out;
  size_t pos = 0;
  while (pos < log.size()) {
    size_t eol = log.find('\n', pos);
    if (eol == std::string_view::npos) eol = log.size();
    const std::string_view line = log.substr(pos, eol - pos);
    pos = eol + 1;
    if (line.find("eleport") == std::string_view::npos) continue;  // Teleporting / teleports / ends teleporting
    const size_t q0 = line.find('\'');
    const size_t q1 = q0 == std::string_view::npos ? q0 : line.find('\'', q0 + 1);
    const size_t tp = line.rfind("time=");
    if (q1 == std::string_view::npos || tp == std::string_view::npos) continue;
    double t = 0;
    const char* b = line.data() + tp + 5;
    auto [p, ec] = std::from_chars(b, line.data() + line.size(), t);
    if (ec != std::errc()) continue;
    out.push_back({std::string(line.substr(q0 + 1, q1 - q0 - 1)), t, true});
  }
  return out;
}

}  // namespace ss
