// A SUMO network (.net.xml) as the dataset generator needs it: lanes with shapes and permissions, edges, junctions,
// connections (with their internal "via" lanes, signal indices and link states) and traffic-light ids.
#pragma once

#include <functional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "absl/status/statusor.h"
#include "engine/geometry/geometry.h"

namespace ss {

enum class SumoEdgeFunction { normal, internal, crossing, walkingarea, connector };

// What a lane carries, from its allow/disallow permissions.
enum class SumoLaneUse {
  road,      // motor vehicles (passenger cars, buses, delivery, ...): possibly bicycles too
  bike,      // bicycles but no motor vehicles
  sidewalk,  // pedestrians only
  other      // rail, ships, nothing
};

struct SumoLane {
  std::string id;
  int edge = -1;  // index into SumoNet::edges
  int index = 0;  // 0 is the rightmost lane of its edge
  double speed = 0, length = 0, width = 3.2;
  std::vector<Vec2> shape;
  SumoLaneUse use = SumoLaneUse::road;
};

struct SumoEdge {
  std::string id;
  SumoEdgeFunction function = SumoEdgeFunction::normal;
  std::string from, to;        // junction ids (normal edges)
  std::vector<int> lanes;      // indices into SumoNet::lanes, by lane index
};

struct SumoJunction {
  std::string id, type;  // type: traffic_light, priority, priority_stop, allway_stop, dead_end, internal, ...
  Vec2 position;
};

struct SumoConnection {
  int from_lane = -1, to_lane = -1;  // indices into SumoNet::lanes; -1 when the lane is not in the network
  int via = -1;                      // the internal lane the connection drives through, -1 when none
  std::string tl;                    // controlling traffic light, empty when none
  int link_index = -1;               // index into the traffic light's state string
  char dir = 's';                    // s straight, l left, r right, t turnaround, L/R partial left/right, invalid
  char state = 'M';                  // link state: M major, m minor, s stop, w all-way stop, o off, = equal, ...
};

struct SumoNet {
  std::vector<SumoEdge> edges;
  std::vector<SumoLane> lanes;
  std::vector<SumoJunction> junctions;
  std::vector<SumoConnection> connections;
  std::vector<std::string> traffic_lights;  // tlLogic ids, in file order, without duplicates
  std::unordered_map<std::string, int> lane_by_id, edge_by_id;

  int find_lane(std::string_view id) const;  // -1 when absent
};

SumoLaneUse sumo_lane_use(std::string_view allow, std::string_view disallow);

// Parses a .net.xml text; `where` names it in errors.
absl::StatusOr<SumoNet> parse_sumo_net(std::string_view xml, const std::string& where);

// Sets every traffic light's offset (the `offset` attribute of each <tlLogic>) to the one `offset_of(index)` gives,
// index counting tlLogic elements in file order. netconvert builds every program with offset 0, which would make all
// signals of a network switch in lockstep.
std::string with_tls_offsets(std::string_view xml, const std::function<int(int)>& offset_of);

// Parses "x,y x,y ..." (a third coordinate, when present, is ignored).
absl::StatusOr<std::vector<Vec2>> parse_sumo_shape(std::string_view text);

}  // namespace ss
