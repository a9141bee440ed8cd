#include "engine/scenario/scenario.h"

namespace ss {

const char* object_type_name(ObjectType t) {
  switch (t) {
    case ObjectType::unset: return "unset";
    case ObjectType::vehicle: return "vehicle";
    case ObjectType::pedestrian: return "pedestrian";
    case ObjectType::cyclist: return "cyclist";
    case ObjectType::other: return "other";
  }
  return "invalid";
}

const char* map_feature_kind_name(MapFeatureKind k) {
  switch (k) {
    case MapFeatureKind::lane: return "lane";
    case MapFeatureKind::road_line: return "road_line";
    case MapFeatureKind::road_edge: return "road_edge";
    case MapFeatureKind::stop_sign: return "stop_sign";
    case MapFeatureKind::crosswalk: return "crosswalk";
    case MapFeatureKind::speed_bump: return "speed_bump";
    case MapFeatureKind::driveway: return "driveway";
  }
  return "invalid";
}

}  // namespace ss
