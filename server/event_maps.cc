#include "server/event_maps.h"

namespace ss::server {

void EventMaps::add(const std::string& session_id, const std::string& scenario_name,
                    const std::shared_ptr<const Scenario>& scenario) {
  std::lock_guard<std::mutex> l(mu_);
  auto& slot = scenario_name.empty() ? by_session_[session_id] : by_name_[scenario_name];
  if (!slot) slot = std::make_shared<const EventMap>(event_map_from_scenario(*scenario));
}

void EventMaps::fork(const std::string& from, const std::string& to) {
  std::lock_guard<std::mutex> l(mu_);
  auto it = by_session_.find(from);
  if (it != by_session_.end()) by_session_[to] = it->second;
}

void EventMaps::remove(const std::string& session_id) {
  std::lock_guard<std::mutex> l(mu_);
  by_session_.erase(session_id);
}

std::shared_ptr<const EventMap> EventMaps::find(const std::string& session_id, const std::string& scenario_name) {
  {
    std::lock_guard<std::mutex> l(mu_);
    if (auto it = by_session_.find(session_id); it != by_session_.end()) return it->second;
    if (scenario_name.empty()) return nullptr;
    if (auto it = by_name_.find(scenario_name); it != by_name_.end()) return it->second;
  }
  // A bundled scenario's session this server did not create (restored from a snapshot): build its map once.
  auto scenario = engine_scenario(engine_, SessionSource{scenario_name, {}});
  if (!scenario.ok()) return nullptr;
  add(session_id, scenario_name, *scenario);
  return find(session_id, scenario_name);
}

}  // namespace ss::server
