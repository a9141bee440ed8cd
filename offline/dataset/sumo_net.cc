#include "offline/dataset/sumo_net.h"

#include <charconv>
#include <cmath>
#include <set>

#include "absl/strings/str_cat.h"
#include "offline/dataset/xml_scan.h"

namespace ss {
namespace {

constexpr double kMaxSumoCoordinate = 1e6;

bool list_has(std::string_view list, std::string_view word) {
  size_t i = 0;
  while (i < list.size()) {
    while (i < list.size() && list[i] == ' ') ++i;
    size_t j = i;
    while (j < list.size() && list[j] != ' ') ++j;
    if (list.substr(i, j - i) == word) return true;
    i = j;
  }
  return false;
}

absl::StatusOr<SumoEdgeFunction> edge_function(std::string_view f) {
  if (f.empty() || f == "normal") return SumoEdgeFunction::normal;
  if (f == "internal") return SumoEdgeFunction::internal;
  if (f == "crossing") return SumoEdgeFunction::crossing;
  if (f == "walkingarea") return SumoEdgeFunction::walkingarea;
  if (f == "connector") return SumoEdgeFunction::connector;
  return absl::InvalidArgumentError(absl::StrCat("unknown edge function \"", std::string(f), "\""));
}

// Connections name lanes as (edge, lane index); they are resolved once every edge is known.
struct RawConnection {
  std::string from, to, via, tl;
  int from_lane = 0, to_lane = 0, link_index = -1;
  char dir = 's', state = 'M';
  int line = 0;
};

}  // namespace

SumoLaneUse sumo_lane_use(std::string_view allow, std::string_view disallow) {
  auto allowed = [&](std::string_view c) {
    if (!allow.empty()) return list_has(allow, c) || list_has(allow, "all");
    if (!disallow.empty()) return !list_has(disallow, c) && !list_has(disallow, "all");
    return true;
  };
  for (std::string_view c : {"passenger", "bus", "delivery", "truck", "taxi", "coach", "hov", "evehicle"})
    if (allowed(c)) return SumoLaneUse::road;
  if (allowed("bicycle")) return SumoLaneUse::bike;
  if (allowed("pedestrian")) return SumoLaneUse::sidewalk;
  return SumoLaneUse::other;
}

int SumoNet::find_lane(std::string_view id) const {
  auto it = lane_by_id.find(std::string(id));
  return it == lane_by_id.end() ? -1 : it->second;
}

absl::StatusOr<std::vector<Vec2>> parse_sumo_shape(std::string_view text) {
  std::vector<Vec2> pts;
  size_t i = 0;
  while (i < text.size()) {
    while (i < text.size() && text[i] == ' ') ++i;
    if (i >= text.size()) break;
    size_t j = text.find(' ', i);
    if (j == std::string_view::npos) j = text.size();
    const std::string_view p = text.substr(i, j - i);
    double c[2];
    const char* at = p.data();
    const char* end = p.data() + p.size();
    for (int k = 0; k < 2; ++k) {
      auto [q, ec] = std::from_chars(at, end, c[k]);
      if (ec != std::errc() || (k == 0 && (q == end || *q != ',')) || (k == 1 && q != end && *q != ','))
        return absl::InvalidArgumentError(absl::StrCat("bad shape point \"", std::string(p), "\""));
      // Networks span kilometres; anything beyond 1000 km (or not finite) is corruption, and would make the
      // 0.5 m resampling of the map explode.
      if (!(std::abs(c[k]) <= kMaxSumoCoordinate))
        return absl::InvalidArgumentError(absl::StrCat("shape point \"", std::string(p), "\" is out of range"));
      at = q + 1;
    }
    pts.push_back({c[0], c[1]});
    i = j;
  }
  return pts;
}

absl::StatusOr<SumoNet> parse_sumo_net(std::string_view xml, const std::string& where) {
  SumoNet net;
  XmlScanner x(xml, where);
  std::vector<RawConnection> raw;
  std::set<std::string> tl_seen;
  int current_edge = -1;
  bool saw_net = false;
  while (true) {
    auto more = x.next();
    if (!more.ok()) return more.status();
    if (!*more) break;
    const std::string_view name = x.name();
    if (!x.is_start()) {
      if (name == "edge") current_edge = -1;
      continue;
    }
    if (name == "net") {
      saw_net = true;
    } else if (name == "edge") {
      SumoEdge e;
      e.id = x.get("id");
      auto fn = edge_function(x.get("function"));
      if (!fn.ok()) return absl::InvalidArgumentError(absl::StrCat(x.location(), ": edge ", e.id, ": ", fn.status().message()));
      e.function = *fn;
      e.from = x.get("from");
      e.to = x.get("to");
      if (net.edge_by_id.count(e.id)) return absl::InvalidArgumentError(absl::StrCat(x.location(), ": duplicate edge ", e.id));
      net.edge_by_id[e.id] = static_cast<int>(net.edges.size());
      net.edges.push_back(std::move(e));
      current_edge = x.self_closing() ? -1 : static_cast<int>(net.edges.size()) - 1;
    } else if (name == "lane" && current_edge >= 0) {
      SumoLane l;
      l.id = x.get("id");
      l.edge = current_edge;
      auto index = x.integer("index");
      auto speed = x.number("speed");
      auto length = x.number("length");
      auto width = x.number_or("width", 3.2);  // SUMO's default lane width
      if (!index.ok()) return (index.status());
      if (!speed.ok()) return (speed.status());
      if (!length.ok()) return (length.status());
      if (!width.ok()) return (width.status());
      l.index = *index;
      l.speed = *speed;
      l.length = *length;
      l.width = *width;
      auto shape = parse_sumo_shape(x.get("shape"));
      if (!shape.ok()) return absl::InvalidArgumentError(absl::StrCat(x.location(), ": lane ", l.id, ": ", shape.status().message()));
      if (shape->size() < 2) return absl::InvalidArgumentError(absl::StrCat(x.location(), ": lane ", l.id, " has fewer than 2 shape points"));
      l.shape = std::move(*shape);
      l.use = sumo_lane_use(x.get("allow"), x.get("disallow"));
      if (net.lane_by_id.count(l.id)) return absl::InvalidArgumentError(absl::StrCat(x.location(), ": duplicate lane ", l.id));
      net.lane_by_id[l.id] = static_cast<int>(net.lanes.size());
      net.edges[current_edge].lanes.push_back(static_cast<int>(net.lanes.size()));
      net.lanes.push_back(std::move(l));
    } else if (name == "junction") {
      SumoJunction j;
      j.id = x.get("id");
      j.type = x.get("type");
      auto jx = x.number("x");
      auto jy = x.number("y");
      if (!jx.ok()) return (jx.status());
      if (!jy.ok()) return (jy.status());
      j.position = {*jx, *jy};
      net.junctions.push_back(std::move(j));
    } else if (name == "connection") {
      RawConnection c;
      c.from = x.get("from");
      c.to = x.get("to");
      c.via = x.get("via");
      c.tl = x.get("tl");
      auto fl = x.integer("fromLane");
      auto tl = x.integer("toLane");
      if (!fl.ok()) return (fl.status());
      if (!tl.ok()) return (tl.status());
      c.from_lane = *fl;
      c.to_lane = *tl;
      if (!c.tl.empty()) {
        auto li = x.integer("linkIndex");
        if (!li.ok()) return (li.status());
        c.link_index = *li;
      }
      const std::string dir = x.get("dir", "s"), state = x.get("state", "M");
      c.dir = dir.empty() ? 's' : dir[0];
      c.state = state.empty() ? 'M' : state[0];
      c.line = x.line();
      raw.push_back(std::move(c));
    } else if (name == "tlLogic") {
      const std::string id = x.get("id");
      if (tl_seen.insert(id).second) net.traffic_lights.push_back(id);
    }
  }
  if (!saw_net) return absl::InvalidArgumentError(absl::StrCat(where, ": not a SUMO network (no <net> element)"));
  for (const SumoLane& l : net.lanes)
    if (l.index < 0 || l.index >= static_cast<int>(net.edges[l.edge].lanes.size()) ||
        net.lanes[net.edges[l.edge].lanes[l.index]].id != l.id)
      return absl::InvalidArgumentError(
          absl::StrCat(where, ": edge ", net.edges[l.edge].id, ": lane indices are not 0..n-1 in order"));
  auto lane_of = [&](const std::string& edge, int index) {
    auto it = net.edge_by_id.find(edge);
    if (it == net.edge_by_id.end()) return -1;
    const SumoEdge& e = net.edges[it->second];
    return index >= 0 && index < static_cast<int>(e.lanes.size()) ? e.lanes[index] : -1;
  };
  net.connections.reserve(raw.size());
  for (const RawConnection& r : raw) {
    SumoConnection c;
    c.from_lane = lane_of(r.from, r.from_lane);
    c.to_lane = lane_of(r.to, r.to_lane);
    if (c.from_lane < 0 || c.to_lane < 0)
      return absl::InvalidArgumentError(absl::StrCat(where, ":", r.line, ": connection ", r.from, "_", r.from_lane,
                                                     " -> ", r.to, "_", r.to_lane, " names a lane the network lacks"));
    if (!r.via.empty()) {
      c.via = net.find_lane(r.via);
      if (c.via < 0)
        return absl::InvalidArgumentError(absl::StrCat(where, ":", r.line, ": connection via unknown lane ", r.via));
    }
    c.tl = r.tl;
    c.link_index = r.link_index;
    c.dir = r.dir;
    c.state = r.state;
    net.connections.push_back(std::move(c));
  }
  return net;
}

std::string with_tls_offsets(std::string_view xml, const std::function<int(int)>& offset_of) {
  std::string out;
  out.reserve(xml.size() + 64);
  size_t pos = 0;
  int index = 0;
  while (true) {
    const size_t tag = xml.find("<tlLogic ", pos);
    if (tag == std::string_view::npos) break;
    const size_t close = xml.find('>', tag);
    if (close == std::string_view::npos) break;
    const std::string_view head = xml.substr(tag, close - tag);
    const size_t attr = head.find(" offset=\"");
    out.append(xml.substr(pos, tag - pos));
    const std::string offset = std::to_string(offset_of(index++));
    if (attr == std::string_view::npos) {
      const bool empty_element = head.ends_with("/");
      out.append(head.substr(0, head.size() - (empty_element ? 1 : 0)));
      out.append(" offset=\"" + offset + "\"");
      if (empty_element) out.append("/");
    } else {
      const size_t value = attr + 9;
      const size_t end = head.find('"', value);
      out.append(head.substr(0, value));
      out.append(offset);
      out.append(head.substr(end));
    }
    pos = close;
  }
  out.append(xml.substr(pos));
  return out;
}

}  // namespace ss
