#include "engine/scenario/womd_proto.h"

#include <algorithm>
#include <bit>
#include <climits>
#include <cstdint>

#include "absl/strings/str_cat.h"
#include "engine/scenario/tfrecord.h"
#include "engine/scenario/validate.h"
#include "engine/scenario/wire_check.h"
#include "womd/scenario.pb.h"

namespace ss {
namespace {

namespace wo = waymo::open_dataset;

// ---- proto -> Scenario ----

MapPoint from_proto(const wo::MapPoint& p) { return {p.x(), p.y(), p.z()}; }

template <class Points>
std::vector<MapPoint> from_proto(const Points& pts) {
  std::vector<MapPoint> out;
  out.reserve(pts.size());
  for (const auto& p : pts) out.push_back(from_proto(p));
  return out;
}

BoundarySegment from_proto(const wo::BoundarySegment& b) {
  return {b.lane_start_index(), b.lane_end_index(), b.boundary_feature_id(), static_cast<int32_t>(b.boundary_type())};
}

template <class Segments>
std::vector<BoundarySegment> boundaries_from_proto(const Segments& segs) {
  std::vector<BoundarySegment> out;
  out.reserve(segs.size());
  for (const auto& b : segs) out.push_back(from_proto(b));
  return out;
}

template <class Neighbors>
std::vector<LaneNeighbor> neighbors_from_proto(const Neighbors& ns) {
  std::vector<LaneNeighbor> out;
  out.reserve(ns.size());
  for (const wo::LaneNeighbor& n : ns)
    out.push_back({n.feature_id(), n.self_start_index(), n.self_end_index(), n.neighbor_start_index(),
                   n.neighbor_end_index(), boundaries_from_proto(n.boundaries())});
  return out;
}

ObjectState from_proto(const wo::ObjectState& o) {
  ObjectState s;
  s.x = o.center_x();
  s.y = o.center_y();
  s.z = o.center_z();
  s.length = o.length();
  s.width = o.width();
  s.height = o.height();
  s.heading = o.heading();
  s.vx = o.velocity_x();
  s.vy = o.velocity_y();
  s.valid = o.valid();
  return s;
}

absl::Status map_feature_from_proto(const wo::MapFeature& f, size_t index, const std::string& where,
                                    MapFeature* out) {
  out->id = f.id();
  switch (f.feature_data_case()) {
    case wo::MapFeature::kLane: {
      const wo::LaneCenter& l = f.lane();
      out->kind = MapFeatureKind::lane;
      out->subtype = l.type();
      out->points = from_proto(l.polyline());
      out->lane.speed_limit_mph = l.speed_limit_mph();
      out->lane.interpolating = l.interpolating();
      out->lane.entry_lanes.assign(l.entry_lanes().begin(), l.entry_lanes().end());
      out->lane.exit_lanes.assign(l.exit_lanes().begin(), l.exit_lanes().end());
      out->lane.left_neighbors = neighbors_from_proto(l.left_neighbors());
      out->lane.right_neighbors = neighbors_from_proto(l.right_neighbors());
      out->lane.left_boundaries = boundaries_from_proto(l.left_boundaries());
      out->lane.right_boundaries = boundaries_from_proto(l.right_boundaries());
      break;
    }
    case wo::MapFeature::kRoadLine:
      out->kind = MapFeatureKind::road_line;
      out->subtype = f.road_line().type();
      out->points = from_proto(f.road_line().polyline());
      break;
    case wo::MapFeature::kRoadEdge:
      out->kind = MapFeatureKind::road_edge;
      out->subtype = f.road_edge().type();
      out->points = from_proto(f.road_edge().polyline());
      break;
    case wo::MapFeature::kStopSign:
      out->kind = MapFeatureKind::stop_sign;
      if (f.stop_sign().has_position()) out->points.push_back(from_proto(f.stop_sign().position()));
      out->stop_sign_lanes.assign(f.stop_sign().lane().begin(), f.stop_sign().lane().end());
      break;
    case wo::MapFeature::kCrosswalk:
      out->kind = MapFeatureKind::crosswalk;
      out->points = from_proto(f.crosswalk().polygon());
      break;
    case wo::MapFeature::kSpeedBump:
      out->kind = MapFeatureKind::speed_bump;
      out->points = from_proto(f.speed_bump().polygon());
      break;
    case wo::MapFeature::kDriveway:
      out->kind = MapFeatureKind::driveway;
      out->points = from_proto(f.driveway().polygon());
      break;
    case wo::MapFeature::FEATURE_DATA_NOT_SET:
      // scenario.h has no "no kind": taking it for an empty lane would invent data.
      return absl::InvalidArgumentError(absl::StrCat(where, ": Scenario.map_features[", index, "] (id ", f.id(),
                                                     "): no feature data (none of lane, road_line, road_edge, "
                                                     "stop_sign, crosswalk, speed_bump, driveway is set)"));
  }
  return absl::OkStatus();
}

absl::StatusOr<Scenario> from_proto(const wo::Scenario& p, const std::string& where) {
  Scenario s;
  s.id = p.scenario_id();
  s.timestamps.assign(p.timestamps_seconds().begin(), p.timestamps_seconds().end());
  s.current_time_index = p.current_time_index();

  s.tracks.reserve(p.tracks_size());
  for (const wo::Track& t : p.tracks()) {
    Track& tr = s.tracks.emplace_back();
    tr.id = t.id();
    tr.type = static_cast<ObjectType>(t.object_type());
    tr.states.reserve(t.states_size());
    for (const wo::ObjectState& o : t.states()) tr.states.push_back(from_proto(o));
  }

  s.map_features.resize(p.map_features_size());
  for (int i = 0; i < p.map_features_size(); ++i)
    if (auto st = map_feature_from_proto(p.map_features(i), i, where, &s.map_features[i]); !st.ok()) return st;

  s.signals.reserve(p.dynamic_map_states_size());
  for (const wo::DynamicMapState& d : p.dynamic_map_states()) {
    auto& frame = s.signals.emplace_back();
    frame.reserve(d.lane_states_size());
    for (const wo::TrafficSignalLaneState& ls : d.lane_states())
      frame.push_back({ls.lane(), static_cast<SignalState>(ls.state()), from_proto(ls.stop_point()),
                       ls.has_stop_point()});
  }

  s.sdc_track_index = p.has_sdc_track_index() ? p.sdc_track_index() : -1;
  s.objects_of_interest.assign(p.objects_of_interest().begin(), p.objects_of_interest().end());
  for (const wo::RequiredPrediction& r : p.tracks_to_predict())
    s.tracks_to_predict.push_back({r.track_index(), static_cast<int32_t>(r.difficulty())});
  s.laser_data.assign(p.compressed_frame_laser_data().begin(), p.compressed_frame_laser_data().end());
  s.camera_tokens.assign(p.frame_camera_tokens().begin(), p.frame_camera_tokens().end());
  return s;
}

// ---- Scenario -> proto ----

// Sets an enum field; a value the WOMD enum does not have goes to the unknown fields with the same field number, so
// it is serialized as is (and rejected on reading) instead of tripping libprotobuf's debug assertion.
template <class Msg, class Enum>
void set_enum(Msg* m, void (Msg::*set)(Enum), bool (*is_valid)(int), int field_number, int32_t value) {
  if (is_valid(value))
    (m->*set)(static_cast<Enum>(value));
  else
    m->mutable_unknown_fields()->AddVarint(field_number, static_cast<uint64_t>(static_cast<int64_t>(value)));
}

void to_proto(const MapPoint& p, wo::MapPoint* out) {
  out->set_x(p.x);
  out->set_y(p.y);
  out->set_z(p.z);
}

template <class Points>
void points_to_proto(const std::vector<MapPoint>& pts, Points* out) {
  out->Reserve(static_cast<int>(pts.size()));
  for (const MapPoint& p : pts) to_proto(p, out->Add());
}

void to_proto(const BoundarySegment& b, wo::BoundarySegment* out) {
  out->set_lane_start_index(b.lane_start_index);
  out->set_lane_end_index(b.lane_end_index);
  out->set_boundary_feature_id(b.boundary_feature_id);
  set_enum(out, &wo::BoundarySegment::set_boundary_type, wo::RoadLine_RoadLineType_IsValid,
           wo::BoundarySegment::kBoundaryTypeFieldNumber, b.boundary_type);
}

template <class Segments>
void boundaries_to_proto(const std::vector<BoundarySegment>& bs, Segments* out) {
  for (const BoundarySegment& b : bs) to_proto(b, out->Add());
}

template <class Neighbors>
void neighbors_to_proto(const std::vector<LaneNeighbor>& ns, Neighbors* out) {
  for (const LaneNeighbor& n : ns) {
    wo::LaneNeighbor* o = out->Add();
    o->set_feature_id(n.feature_id);
    o->set_self_start_index(n.self_start_index);
    o->set_self_end_index(n.self_end_index);
    o->set_neighbor_start_index(n.neighbor_start_index);
    o->set_neighbor_end_index(n.neighbor_end_index);
    boundaries_to_proto(n.boundaries, o->mutable_boundaries());
  }
}

template <class T>
bool zero_bits(T v) {
  return std::bit_cast<std::conditional_t<sizeof(T) == 8, uint64_t, uint32_t>>(v) == 0;
}

void to_proto(const ObjectState& s, wo::ObjectState* o) {
  // Real WOMD files give an invalid state only center_z and valid; write it the same way when nothing else is set
  // (bit for bit, so -0.0 and NaN payloads survive), and write every field otherwise.
  const bool sparse = !s.valid && zero_bits(s.x) && zero_bits(s.y) && zero_bits(s.length) && zero_bits(s.width) &&
                      zero_bits(s.height) && zero_bits(s.heading) && zero_bits(s.vx) && zero_bits(s.vy);
  if (!sparse) {
    o->set_center_x(s.x);
    o->set_center_y(s.y);
  }
  o->set_center_z(s.z);
  if (!sparse) {
    o->set_length(s.length);
    o->set_width(s.width);
    o->set_height(s.height);
    o->set_heading(s.heading);
    o->set_velocity_x(s.vx);
    o->set_velocity_y(s.vy);
  }
  o->set_valid(s.valid);
}

void to_proto(const MapFeature& f, wo::MapFeature* o) {
  o->set_id(f.id);
  switch (f.kind) {
    case MapFeatureKind::lane: {
      wo::LaneCenter* l = o->mutable_lane();
      l->set_speed_limit_mph(f.lane.speed_limit_mph);
      set_enum(l, &wo::LaneCenter::set_type, wo::LaneCenter_LaneType_IsValid, wo::LaneCenter::kTypeFieldNumber,
               f.subtype);
      if (f.lane.interpolating) l->set_interpolating(true);
      points_to_proto(f.points, l->mutable_polyline());
      l->mutable_entry_lanes()->Add(f.lane.entry_lanes.begin(), f.lane.entry_lanes.end());
      l->mutable_exit_lanes()->Add(f.lane.exit_lanes.begin(), f.lane.exit_lanes.end());
      neighbors_to_proto(f.lane.left_neighbors, l->mutable_left_neighbors());
      neighbors_to_proto(f.lane.right_neighbors, l->mutable_right_neighbors());
      boundaries_to_proto(f.lane.left_boundaries, l->mutable_left_boundaries());
      boundaries_to_proto(f.lane.right_boundaries, l->mutable_right_boundaries());
      break;
    }
    case MapFeatureKind::road_line: {
      wo::RoadLine* r = o->mutable_road_line();
      set_enum(r, &wo::RoadLine::set_type, wo::RoadLine_RoadLineType_IsValid, wo::RoadLine::kTypeFieldNumber,
               f.subtype);
      points_to_proto(f.points, r->mutable_polyline());
      break;
    }
    case MapFeatureKind::road_edge: {
      wo::RoadEdge* r = o->mutable_road_edge();
      set_enum(r, &wo::RoadEdge::set_type, wo::RoadEdge_RoadEdgeType_IsValid, wo::RoadEdge::kTypeFieldNumber,
               f.subtype);
      points_to_proto(f.points, r->mutable_polyline());
      break;
    }
    case MapFeatureKind::stop_sign: {
      wo::StopSign* st = o->mutable_stop_sign();
      st->mutable_lane()->Add(f.stop_sign_lanes.begin(), f.stop_sign_lanes.end());
      if (!f.points.empty()) to_proto(f.points.front(), st->mutable_position());
      break;
    }
    case MapFeatureKind::crosswalk:
      points_to_proto(f.points, o->mutable_crosswalk()->mutable_polygon());
      break;
    case MapFeatureKind::speed_bump:
      points_to_proto(f.points, o->mutable_speed_bump()->mutable_polygon());
      break;
    case MapFeatureKind::driveway:
      points_to_proto(f.points, o->mutable_driveway()->mutable_polygon());
      break;
  }
  // An unknown kind leaves feature_data unset: reading it back is an error, as it should be.
}

void to_proto(const Scenario& s, wo::Scenario* p) {
  p->set_scenario_id(s.id);
  p->mutable_timestamps_seconds()->Add(s.timestamps.begin(), s.timestamps.end());
  p->set_current_time_index(s.current_time_index);
  p->mutable_tracks()->Reserve(static_cast<int>(s.tracks.size()));
  for (const Track& t : s.tracks) {
    wo::Track* o = p->add_tracks();
    o->set_id(t.id);
    set_enum(o, &wo::Track::set_object_type, wo::Track_ObjectType_IsValid, wo::Track::kObjectTypeFieldNumber,
             static_cast<int32_t>(t.type));
    o->mutable_states()->Reserve(static_cast<int>(t.states.size()));
    for (const ObjectState& st : t.states) to_proto(st, o->add_states());
  }
  for (const auto& frame : s.signals) {
    wo::DynamicMapState* d = p->add_dynamic_map_states();
    for (const SignalLaneState& ls : frame) {
      wo::TrafficSignalLaneState* o = d->add_lane_states();
      o->set_lane(ls.lane);
      set_enum(o, &wo::TrafficSignalLaneState::set_state, wo::TrafficSignalLaneState_State_IsValid,
               wo::TrafficSignalLaneState::kStateFieldNumber, static_cast<int32_t>(ls.state));
      if (ls.has_stop_point) to_proto(ls.stop_point, o->mutable_stop_point());
    }
  }
  p->mutable_map_features()->Reserve(static_cast<int>(s.map_features.size()));
  for (const MapFeature& f : s.map_features) to_proto(f, p->add_map_features());
  if (s.sdc_track_index != -1) p->set_sdc_track_index(s.sdc_track_index);
  p->mutable_objects_of_interest()->Add(s.objects_of_interest.begin(), s.objects_of_interest.end());
  for (const RequiredPrediction& r : s.tracks_to_predict) {
    wo::RequiredPrediction* o = p->add_tracks_to_predict();
    o->set_track_index(r.track_index);
    set_enum(o, &wo::RequiredPrediction::set_difficulty, wo::RequiredPrediction_DifficultyLevel_IsValid,
             wo::RequiredPrediction::kDifficultyFieldNumber, r.difficulty);
  }
  for (const std::string& b : s.laser_data) p->add_compressed_frame_laser_data(b);
  for (const std::string& b : s.camera_tokens) p->add_frame_camera_tokens(b);
}

bool point_is_zero(const MapPoint& p) { return zero_bits(p.x) && zero_bits(p.y) && zero_bits(p.z); }

// ---- limits, on the wire ----

// Calls f(number, payload) for each length-delimited field of a message's wire bytes, skipping the others; false when
// the bytes are malformed (check_wire then names the problem).
template <class F>
bool for_each_len_field(std::string_view b, F&& f) {
  size_t pos = 0;
  auto varint = [&](uint64_t* v) {
    *v = 0;
    for (int shift = 0; shift < 64 && pos < b.size(); shift += 7) {
      const uint8_t c = static_cast<uint8_t>(b[pos++]);
      *v |= static_cast<uint64_t>(c & 0x7F) << shift;
      if (!(c & 0x80)) return true;
    }
    return false;
  };
  while (pos < b.size()) {
    uint64_t tag, v;
    if (!varint(&tag)) return false;
    switch (tag & 7) {
      case 0:
        if (!varint(&v)) return false;
        break;
      case 1:
        pos += 8;
        break;
      case 5:
        pos += 4;
        break;
      case 2:
        if (!varint(&v) || v > b.size() - pos) return false;
        f(static_cast<int>(tag >> 3), b.substr(pos, v));
        pos += v;
        break;
      default:
        return false;  // groups: check_wire names them
    }
    if (pos > b.size()) return false;
  }
  return true;
}

int64_t count_len_fields(std::string_view b, int number) {
  int64_t n = 0;
  for_each_len_field(b, [&](int k, std::string_view) { n += k == number; });
  return n;
}

absl::Status check_womd_limits(std::string_view bytes, const WomdLimits& limits, const std::string& where) {
  int64_t tracks = 0, features = 0, frames = 0, dynamic = 0, predicted = 0, points = 0;
  int64_t most_states = 0, most_lane_states = 0;
  for_each_len_field(bytes, [&](int number, std::string_view payload) {
    switch (number) {
      case 1:  // timestamps_seconds, packed doubles (an unpacked one is not length-delimited and not counted)
        frames += static_cast<int64_t>(payload.size() / 8);
        break;
      case 2:
        ++tracks;
        if (tracks <= limits.max_tracks) most_states = std::max(most_states, count_len_fields(payload, 3));
        break;
      case 7:
        ++dynamic;
        most_lane_states = std::max(most_lane_states, count_len_fields(payload, 1));
        break;
      case 8:
        ++features;
        // The feature's one member (lane, road line, ...), and what it holds: points, boundaries, neighbours (and a
        // neighbour's boundaries).
        for_each_len_field(payload, [&](int, std::string_view member) {
          for_each_len_field(member, [&](int, std::string_view part) {
            ++points;
            points += count_len_fields(part, 5);  // LaneNeighbor.boundaries
          });
        });
        break;
      case 11:
        ++predicted;
        break;
      default:
        break;
    }
  });
  auto over = [&](int64_t n, const char* what, int limit) {
    return absl::ResourceExhaustedError(absl::StrCat(where, ": ", n, " ", what, ", above the limit of ", limit));
  };
  if (tracks > limits.max_tracks) return over(tracks, "tracks", limits.max_tracks);
  if (predicted > limits.max_tracks) return over(predicted, "tracks_to_predict", limits.max_tracks);
  if (features > limits.max_map_features) return over(features, "map features", limits.max_map_features);
  if (most_lane_states > limits.max_map_features)
    return over(most_lane_states, "lane states in one dynamic map state", limits.max_map_features);
  if (frames > limits.max_frames) return over(frames, "frames (timestamps_seconds)", limits.max_frames);
  if (most_states > limits.max_frames) return over(most_states, "states in one track", limits.max_frames);
  if (dynamic > limits.max_frames) return over(dynamic, "dynamic map states", limits.max_frames);
  if (points > limits.max_map_points)
    return over(points, "map points (polylines, polygons, lane boundaries and neighbours)", limits.max_map_points);
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<Scenario> scenario_from_womd_bytes(std::string_view bytes, const std::string& where,
                                                  const WomdLimits& limits) {
  if (bytes.size() > static_cast<size_t>(INT_MAX))
    return absl::InvalidArgumentError(
        absl::StrCat(where, ": ", bytes.size(), " bytes is too large for one Scenario proto"));
  if (auto st = check_womd_limits(bytes, limits, where); !st.ok()) return st;
  if (auto st = check_wire(bytes, *wo::Scenario::descriptor(), where); !st.ok()) return st;
  wo::Scenario proto;
  if (!proto.ParseFromArray(bytes.data(), static_cast<int>(bytes.size())))
    return absl::InvalidArgumentError(absl::StrCat(where, ": libprotobuf cannot parse the Scenario"));
  auto s = from_proto(proto, where);
  if (!s.ok()) return s.status();
  if (auto st = validate_scenario(*s, where); !st.ok()) return st;
  return s;
}

std::string scenario_to_womd_bytes(const Scenario& s) {
  wo::Scenario p;
  to_proto(s, &p);
  std::string out;
  p.SerializeToString(&out);
  return out;
}

absl::Status check_womd_representable(const Scenario& s, const std::string& where) {
  auto bad = [&](const std::string& what) { return absl::InvalidArgumentError(absl::StrCat(where, ": ", what)); };
  for (size_t i = 0; i < s.map_features.size(); ++i) {
    const MapFeature& f = s.map_features[i];
    const std::string name =
        absl::StrCat("map_features[", i, "] (id ", f.id, ", ", map_feature_kind_name(f.kind), ")");
    const int kind = static_cast<int>(f.kind);
    if (kind < static_cast<int>(MapFeatureKind::lane) || kind > static_cast<int>(MapFeatureKind::driveway))
      return bad(absl::StrCat(name, ": kind ", kind, " has no WOMD equivalent"));
    if (f.kind != MapFeatureKind::lane && !(f.lane == LaneInfo{}))
      return bad(absl::StrCat(name, ": lane data on a feature that is not a lane"));
    if (f.kind != MapFeatureKind::stop_sign && !f.stop_sign_lanes.empty())
      return bad(absl::StrCat(name, ": stop_sign_lanes on a feature that is not a stop sign"));
    const bool has_subtype = f.kind == MapFeatureKind::lane || f.kind == MapFeatureKind::road_line ||
                             f.kind == MapFeatureKind::road_edge;
    if (!has_subtype && f.subtype != 0)
      return bad(absl::StrCat(name, ": subtype ", f.subtype, " on a kind that has none"));
    if (f.kind == MapFeatureKind::stop_sign && f.points.size() > 1)
      return bad(absl::StrCat(name, ": ", f.points.size(), " points; a WOMD stop sign has one position"));
  }
  for (size_t t = 0; t < s.signals.size(); ++t)
    for (size_t k = 0; k < s.signals[t].size(); ++k)
      if (!s.signals[t][k].has_stop_point && !point_is_zero(s.signals[t][k].stop_point))
        return bad(absl::StrCat("dynamic_map_states[", t, "].lane_states[", k,
                                "]: a stop_point with has_stop_point false"));
  return absl::OkStatus();
}

absl::StatusOr<std::string> encode_womd_scenario(const Scenario& s, const std::string& where) {
  if (auto st = check_womd_representable(s, where); !st.ok()) return st;
  wo::Scenario p;
  to_proto(s, &p);
  const size_t size = p.ByteSizeLong();
  if (size > kMaxTfRecordLength)
    return absl::InvalidArgumentError(
        absl::StrCat(where, ": the scenario encodes to ", size, " bytes, more than a record may hold (",
                     kMaxTfRecordLength, ")"));
  std::string out;
  if (!p.SerializeToString(&out))
    return absl::InternalError(absl::StrCat(where, ": libprotobuf failed to serialize the scenario"));
  return out;
}

}  // namespace ss
