// The road map each session's events are measured on (engine/sim/events.h). The engine's session does not report
// events itself yet: its tick clock is in the session manager (issue 12 moves it into the engine, and the events
// belong there then). Until that, the handlers keep the maps here: bundled scenarios' by name, shared by their
// sessions; client-sent scenarios' by session id, from CreateSession to CloseSession (a client-sent session that ends
// by the idle timeout leaves its map here until the server restarts: the handlers do not see that close). Thread-safe.
#pragma once

#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "absl/status/statusor.h"
#include "engine/scenestreamer.h"

namespace ss::server {

class EventMaps {
 public:
  explicit EventMaps(Engine& engine) : engine_(engine) {}

  // Records the map of a new session on `scenario` (the engine's scenario of the session's source).
  void add(const std::string& session_id, const std::string& scenario_name,
           const std::shared_ptr<const Scenario>& scenario);
  // A fork runs on its source's map.
  void fork(const std::string& from, const std::string& to);
  void remove(const std::string& session_id);
  // The map of a session: its own, else its bundled scenario's (also after a restart restored it). nullptr when
  // neither is known: a client-sent scenario's session restored after a restart (its bytes were not kept here).
  std::shared_ptr<const EventMap> find(const std::string& session_id, const std::string& scenario_name);

 private:
  Engine& engine_;
  std::mutex mu_;
  std::map<std::string, std::shared_ptr<const EventMap>> by_name_;     // bundled scenarios
  std::map<std::string, std::shared_ptr<const EventMap>> by_session_;  // client-sent scenarios
};

}  // namespace ss::server
