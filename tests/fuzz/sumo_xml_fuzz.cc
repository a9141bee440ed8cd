// Fuzzes the readers of SUMO's XML (networks, FCD, signal switches, collisions, log lines) and the network -> map
// conversion: no input may crash or hang them; every error is INVALID_ARGUMENT and names the source.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "offline/dataset/sumo_events.h"
#include "offline/dataset/sumo_fcd.h"
#include "offline/dataset/sumo_map.h"
#include "offline/dataset/sumo_net.h"

namespace {

template <class T>
void check(const absl::StatusOr<T>& r, const std::string& where) {
  if (r.ok()) return;
  if (r.status().code() != absl::StatusCode::kInvalidArgument) __builtin_trap();
  if (r.status().message().substr(0, where.size()) != where) __builtin_trap();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  auto net = ss::parse_sumo_net(text, "fuzz.net.xml");
  check(net, "fuzz.net.xml");
  if (net.ok()) {
    const ss::SumoMap map = ss::build_sumo_map(*net);
    if (map.bounds.size() != map.features.size()) __builtin_trap();
    for (const ss::MapFeature& f : map.features)
      if (f.points.empty()) __builtin_trap();
    (void)ss::crop_map(map, {0, 0}, 100);
  }
  const ss::AgentKinds kinds = {{"car", {ss::ObjectType::vehicle, 4.5f, 2.0f, 1.5f}}};
  check(ss::parse_fcd(text, "fuzz.fcd.xml", kinds, {{"p0", "car"}}, 0.1), "fuzz.fcd.xml");
  check(ss::parse_signal_switches(text, "fuzz.tls.xml"), "fuzz.tls.xml");
  check(ss::parse_collisions(text, "fuzz.col.xml"), "fuzz.col.xml");
  (void)ss::parse_teleports(text);
  return 0;
}
