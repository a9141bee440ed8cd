// The engine's scenario: everything the model and the tools need from a Waymo Open Motion Dataset scenario.
// Field meanings and enum values follow the WOMD schema (proto/womd), so a WOMD file converts both ways losslessly.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ss {

// WOMD Track.ObjectType values.
enum class ObjectType : int32_t { unset = 0, vehicle = 1, pedestrian = 2, cyclist = 3, other = 4 };

const char* object_type_name(ObjectType t);

// One track at one 10 Hz frame (WOMD ObjectState). An invalid state carries no meaningful pose.
struct ObjectState {
  double x = 0, y = 0, z = 0;  // box centre, metres
  float length = 0, width = 0, height = 0;
  float heading = 0;           // radians, [-pi, pi)
  float vx = 0, vy = 0;        // m/s, global frame
  bool valid = false;
  bool operator==(const ObjectState&) const = default;
};

struct Track {
  int32_t id = 0;                   // WOMD object id, unique within a scenario
  ObjectType type = ObjectType::unset;
  std::vector<ObjectState> states;  // one per frame (scenario.timestamps)
  bool operator==(const Track&) const = default;
};

struct MapPoint {
  double x = 0, y = 0, z = 0;
  bool operator==(const MapPoint&) const = default;
};

// WOMD MapFeature kinds (the oneof of MapFeature).
enum class MapFeatureKind : int32_t { lane, road_line, road_edge, stop_sign, crosswalk, speed_bump, driveway };

const char* map_feature_kind_name(MapFeatureKind k);

// WOMD RoadLine.RoadLineType values.
enum class RoadLineType : int32_t {
  unknown = 0, broken_single_white = 1, solid_single_white = 2, solid_double_white = 3, broken_single_yellow = 4,
  broken_double_yellow = 5, solid_single_yellow = 6, solid_double_yellow = 7, passing_double_yellow = 8
};

struct BoundarySegment {
  int32_t lane_start_index = 0;
  int32_t lane_end_index = 0;
  int64_t boundary_feature_id = 0;
  int32_t boundary_type = 0;  // RoadLineType value
  bool operator==(const BoundarySegment&) const = default;
};

struct LaneNeighbor {
  int64_t feature_id = 0;
  int32_t self_start_index = 0, self_end_index = 0;
  int32_t neighbor_start_index = 0, neighbor_end_index = 0;
  std::vector<BoundarySegment> boundaries;
  bool operator==(const LaneNeighbor&) const = default;
};

// Lane-only data (WOMD LaneCenter).
struct LaneInfo {
  double speed_limit_mph = 0;
  bool interpolating = false;
  std::vector<int64_t> entry_lanes;  // feature ids
  std::vector<int64_t> exit_lanes;
  std::vector<LaneNeighbor> left_neighbors, right_neighbors;
  std::vector<BoundarySegment> left_boundaries, right_boundaries;
  bool operator==(const LaneInfo&) const = default;
};

struct MapFeature {
  int64_t id = 0;
  MapFeatureKind kind = MapFeatureKind::lane;
  // The kind's WOMD type enum: LaneType (0 undefined, 1 freeway, 2 surface street, 3 bike lane), RoadLineType,
  // RoadEdgeType (0 unknown, 1 boundary, 2 median); 0 for kinds without one.
  int32_t subtype = 0;
  // Lanes, lines and edges: the polyline. Crosswalks, speed bumps, driveways: the polygon (WOMD does not repeat the
  // first point). Stop signs: one point, the sign's position.
  std::vector<MapPoint> points;
  LaneInfo lane;                         // kind == lane only
  std::vector<int64_t> stop_sign_lanes;  // kind == stop_sign only: the lanes it controls
  bool operator==(const MapFeature&) const = default;
};

// WOMD TrafficSignalLaneState.State values.
enum class SignalState : int32_t {
  unknown = 0, arrow_stop = 1, arrow_caution = 2, arrow_go = 3, stop = 4, caution = 5, go = 6, flashing_stop = 7,
  flashing_caution = 8
};

struct SignalLaneState {
  int64_t lane = 0;  // lane feature id
  SignalState state = SignalState::unknown;
  MapPoint stop_point;
  bool has_stop_point = false;
  bool operator==(const SignalLaneState&) const = default;
};

struct RequiredPrediction {
  int32_t track_index = 0;
  int32_t difficulty = 0;  // 0 none, 1 level 1, 2 level 2
  bool operator==(const RequiredPrediction&) const = default;
};

struct Scenario {
  std::string id;
  std::vector<double> timestamps;      // seconds, one per frame (10 Hz in WOMD: 91 frames)
  int32_t current_time_index = 0;      // the "now" frame (10 in WOMD)
  std::vector<Track> tracks;
  std::vector<MapFeature> map_features;
  std::vector<std::vector<SignalLaneState>> signals;  // per frame: the signal state of each controlled lane
  int32_t sdc_track_index = -1;        // the self-driving car's track; -1 when the source does not say
  std::vector<int32_t> objects_of_interest;  // track ids
  std::vector<RequiredPrediction> tracks_to_predict;
  // Sensor data of WOMD fields 12 and 13, kept as opaque serialized messages so a conversion loses nothing.
  std::vector<std::string> laser_data, camera_tokens;

  int num_frames() const { return static_cast<int>(timestamps.size()); }
  bool operator==(const Scenario&) const = default;
};


}  // namespace ss
