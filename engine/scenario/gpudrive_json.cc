// GPUDrive / Nocturne JSON -> Scenario.
//
// Decisions, checked against the 227 real files in ../shared/data/womd/json (see that README):
// - Heading units: objects WITH `id` (newer GPUDrive files) are in radians; objects WITHOUT `id` (older Nocturne
//   files) are in degrees and unwrapped (450, -270 occur). A file mixing both is rejected: its unit is unknowable.
//   Every heading is wrapped into [-pi, pi).
// - Invalid steps hold placeholders (-10000 or 0.0001) in every field; they become a default ObjectState with
//   valid=false. Their fields must still have the right JSON types (a corrupt file is not hidden behind valid=false).
//   A VALID step holding the placeholder -10000 is an error naming the field.
// - Missing `height` (all older files): a per-type default, the median height of the objects that do carry one
//   (1,261 in the first 59 files: vehicle 1.66, pedestrian 1.74, cyclist 1.77 m; 11,569 in the 227: 1.67, 1.73,
//   1.80 m), rounded: see default_height().
// - Track id = `id` when present, else the object's index. Map feature id = `id` when present, else the road's index.
//   Duplicate ids are errors.
// - Map feature subtype comes from `map_element_id` (GPUDrive MapElementIds); without one (older files) it is 0.
//   A map_element_id that contradicts `type` is an error; -1 ("unknown") is accepted with any type, subtype 0.
// - Polygons (crosswalk, speed bump, driveway): WOMD does not repeat the first point and none of the real files do
//   either (all 9,149 polygons checked); if a file does, the repeated last point is dropped.
// - Stop signs must have exactly one geometry point (all 1,073 real ones do). JSON carries no controlled lanes.
//   Road geometry has no placeholder convention and is taken as is (z optional, 0 when absent); empty geometry is
//   an error (no real road has one).
// - tl_states (optional; absent = no lights): {lane id: {state[], x[], y[], z[] (optional), time_index[],
//   lane_id[] (optional, must equal the key)}}; entry k is the lane's state at frame time_index[k]. Lanes within a
//   frame are ordered by lane id. No entries at all -> Scenario::signals stays empty.
// - metadata (optional, each key optional): sdc_track_index (-1 when absent), objects_of_interest (must be object
//   ids), tracks_to_predict [{track_index, difficulty (0 when absent)}].
// - timestamps = k / 10 s for the frame count of the objects' arrays (91 in every real file); current_time_index 10.
// - Scenario id = `scenario_id` when present, else `name` without a trailing ".json" (the older files' names are
//   "tfrecord-NNNNN-of-NNNNN_<index>.json", which name the source record).
// - Keys this reader does not use (goalPosition, mark_as_expert, vbd_trajectory, geometry point ids, ...) are
//   ignored. Duplicate keys in one object are errors (a JSON DOM would keep one silently).
// - JSON cannot express NaN or infinities; nlohmann rejects the NaN / Infinity tokens some writers emit, and
//   numbers that overflow a double, as syntax errors that name the field.
#include "engine/scenario/gpudrive_json.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <limits>
#include <new>
#include <optional>
#include <string>
#include <unordered_set>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "engine/geometry/geometry.h"
#include "engine/io/json_strict.h"
#include "engine/scenario/validate.h"

namespace ss {
namespace {

using json = nlohmann::json;

constexpr double kPlaceholder = -10000.0;  // the converters' "no data" value
constexpr int kCurrentTimeIndex = 10;      // WOMD: 1 s of history at 10 Hz, then "now"

std::string quote_user(std::string_view s) { return absl::StrCat("\"", json_printable(s), "\""); }

// Where a value sits in the document, as a chain of stack-allocated links; rendered only when an error names it.
// Each link must outlive the links built on it: keep every level in a named variable.
class Path {
 public:
  Path() = default;
  Path field(std::string_view name) const { return Path(this, name, 0); }
  // A key that is data (a lane id), always rendered in brackets: tl_states["118"].
  Path key(std::string_view k) const {
    Path p(this, k, 0);
    p.bracket_ = true;
    return p;
  }
  Path index(size_t i) const { return Path(this, {}, i); }
  std::string str() const {
    std::string out = parent_ ? parent_->str() : std::string();
    if (!parent_) return out;
    if (is_index_) {
      absl::StrAppend(&out, "[", index_, "]");
    } else if (bracket_) {
      absl::StrAppend(&out, "[", quote_user(name_), "]");
    } else {
      json_append_key(out, name_);
    }
    return out;
  }

 private:
  Path(const Path* parent, std::string_view name, size_t index)
      : parent_(parent), name_(name), index_(index), is_index_(name.data() == nullptr) {}
  const Path* parent_ = nullptr;
  std::string_view name_;
  size_t index_ = 0;
  bool is_index_ = false;
  bool bracket_ = false;
};

ObjectType object_type_from(std::string_view s, bool* ok) {
  *ok = true;
  if (s == "vehicle") return ObjectType::vehicle;
  if (s == "pedestrian") return ObjectType::pedestrian;
  if (s == "cyclist") return ObjectType::cyclist;
  if (s == "unset") return ObjectType::unset;
  if (s == "other") return ObjectType::other;
  *ok = false;
  return ObjectType::unset;
}

// Heights for files without `height`: the medians of the real files' heights (see the top of this file), rounded
// to 5 cm. Unset / other get a vehicle-like 1.5 m.
float default_height(ObjectType t) {
  switch (t) {
    case ObjectType::vehicle: return 1.65f;
    case ObjectType::pedestrian: return 1.75f;
    case ObjectType::cyclist: return 1.75f;
    case ObjectType::unset:
    case ObjectType::other: return 1.5f;
  }
  return 1.5f;
}

std::optional<MapFeatureKind> map_kind_from(std::string_view s) {
  if (s == "lane") return MapFeatureKind::lane;
  if (s == "road_line") return MapFeatureKind::road_line;
  if (s == "road_edge") return MapFeatureKind::road_edge;
  if (s == "stop_sign") return MapFeatureKind::stop_sign;
  if (s == "crosswalk") return MapFeatureKind::crosswalk;
  if (s == "speed_bump") return MapFeatureKind::speed_bump;
  if (s == "driveway") return MapFeatureKind::driveway;
  return std::nullopt;
}

// GPUDrive's MapElementIds -> (kind, WOMD subtype). -1 (unknown) is handled by the caller.
std::optional<std::pair<MapFeatureKind, int32_t>> map_element_from(int64_t id) {
  if (id >= 0 && id <= 3) return std::pair{MapFeatureKind::lane, static_cast<int32_t>(id)};
  if (id >= 5 && id <= 13) return std::pair{MapFeatureKind::road_line, static_cast<int32_t>(id - 5)};
  if (id >= 14 && id <= 16) return std::pair{MapFeatureKind::road_edge, static_cast<int32_t>(id - 14)};
  if (id == 17) return std::pair{MapFeatureKind::stop_sign, 0};
  if (id == 18) return std::pair{MapFeatureKind::crosswalk, 0};
  if (id == 19) return std::pair{MapFeatureKind::speed_bump, 0};
  if (id == 20) return std::pair{MapFeatureKind::driveway, 0};
  return std::nullopt;
}

std::optional<SignalState> signal_state_from(std::string_view s) {
  static constexpr std::pair<std::string_view, SignalState> kStates[] = {
      {"unknown", SignalState::unknown},         {"arrow_stop", SignalState::arrow_stop},
      {"arrow_caution", SignalState::arrow_caution}, {"arrow_go", SignalState::arrow_go},
      {"stop", SignalState::stop},               {"caution", SignalState::caution},
      {"go", SignalState::go},                   {"flashing_stop", SignalState::flashing_stop},
      {"flashing_caution", SignalState::flashing_caution}};
  for (const auto& [name, state] : kStates)
    if (s == name) return state;
  return std::nullopt;
}

// Converts a parsed document; every accessor checks the type first, so nothing here throws.
class Converter {
 public:
  explicit Converter(const std::string& where) : where_(where) {}

  absl::StatusOr<Scenario> convert(const json& root) {
    const Path top;
    if (auto st = expect(root, top, json::value_t::object); !st.ok()) return st;
    Scenario s;
    if (auto st = read_id(root, top, &s); !st.ok()) return st;
    if (auto st = read_objects(root, top, &s); !st.ok()) return st;
    if (auto st = read_roads(root, top, &s); !st.ok()) return st;
    if (auto st = read_lights(root, top, &s); !st.ok()) return st;
    if (auto st = read_metadata(root, top, &s); !st.ok()) return st;
    if (auto st = validate_scenario(s, where_); !st.ok()) return st;
    return s;
  }

 private:
  absl::Status fail(const Path& p, std::string_view what) const {
    std::string path = p.str();
    return absl::InvalidArgumentError(
        absl::StrCat(where_, ": ", path, path.empty() ? "" : ": ", std::string(what)));
  }

  absl::Status expect(const json& v, const Path& p, json::value_t t) const {
    if (v.type() == t) return absl::OkStatus();
    return fail(p, absl::StrCat("expected ", t == json::value_t::object ? "an object" : "an array", ", got ",
                                v.type_name()));
  }

  // The member `name` of object `obj` (at `p`), or null when absent.
  static const json* member(const json& obj, std::string_view name) {
    const auto& o = obj.get_ref<const json::object_t&>();
    auto it = o.find(name);
    return it == o.end() ? nullptr : &it->second;
  }

  absl::Status require(const json& obj, const Path& p, std::string_view name, const json** out) const {
    *out = member(obj, name);
    if (*out) return absl::OkStatus();
    return fail(p, absl::StrCat("missing required key \"", std::string(name), "\""));
  }

  absl::Status number(const json& v, const Path& p, double* out) const {
    if (!v.is_number()) return fail(p, absl::StrCat("expected a number, got ", v.type_name()));
    *out = v.get<double>();
    return absl::OkStatus();
  }

  // An integer in [lo, hi]; a float is accepted when it holds an exact integer (some writers emit 5.0).
  absl::Status integer(const json& v, const Path& p, int64_t lo, int64_t hi, int64_t* out) const {
    int64_t r = 0;
    if (v.is_number_integer() && !v.is_number_unsigned()) {
      r = v.get<int64_t>();
    } else if (v.is_number_unsigned()) {
      uint64_t u = v.get<uint64_t>();
      if (u > static_cast<uint64_t>(hi)) return fail(p, absl::StrCat(u, " is outside [", lo, ", ", hi, "]"));
      r = static_cast<int64_t>(u);
    } else if (v.is_number_float()) {
      double d = v.get<double>();
      if (!(d >= -9223372036854775808.0 && d < 9223372036854775808.0) || std::trunc(d) != d)
        return fail(p, absl::StrCat("expected an integer, got ", d));
      r = static_cast<int64_t>(d);
    } else {
      return fail(p, absl::StrCat("expected an integer, got ", v.type_name()));
    }
    if (r < lo || r > hi) return fail(p, absl::StrCat(r, " is outside [", lo, ", ", hi, "]"));
    *out = r;
    return absl::OkStatus();
  }

  absl::Status string(const json& v, const Path& p, const std::string** out) const {
    if (!v.is_string()) return fail(p, absl::StrCat("expected a string, got ", v.type_name()));
    *out = &v.get_ref<const std::string&>();
    return absl::OkStatus();
  }

  absl::Status boolean(const json& v, const Path& p, bool* out) const {
    if (!v.is_boolean()) return fail(p, absl::StrCat("expected a boolean, got ", v.type_name()));
    *out = v.get<bool>();
    return absl::OkStatus();
  }

  // A number that must be real data: not the placeholder.
  absl::Status real_number(const json& v, const Path& p, double* out) const {
    if (auto st = number(v, p, out); !st.ok()) return st;
    if (*out == kPlaceholder) return fail(p, "holds the placeholder -10000 (no data)");
    return absl::OkStatus();
  }

  // A real number that must also fit a float field of ObjectState.
  absl::Status real_float(const json& v, const Path& p, float* out) const {
    double d = 0;
    if (auto st = real_number(v, p, &d); !st.ok()) return st;
    if (!std::isfinite(static_cast<float>(d))) return fail(p, absl::StrCat(d, " is outside the float range"));
    *out = static_cast<float>(d);
    return absl::OkStatus();
  }

  // A point {x, y, z?}. With `real`, placeholders are errors; otherwise only the types are checked.
  absl::Status point(const json& v, const Path& p, bool real, MapPoint* out) const {
    if (auto st = expect(v, p, json::value_t::object); !st.ok()) return st;
    const char* names[] = {"x", "y", "z"};
    double* dst[] = {&out->x, &out->y, &out->z};
    for (int k = 0; k < 3; ++k) {
      const json* c = member(v, names[k]);
      const Path cp = p.field(names[k]);
      if (!c) {
        if (k == 2) {
          *dst[k] = 0;  // z is optional everywhere in this format
          continue;
        }
        return fail(p, absl::StrCat("missing required key \"", names[k], "\""));
      }
      auto st = real ? real_number(*c, cp, dst[k]) : number(*c, cp, dst[k]);
      if (!st.ok()) return st;
    }
    return absl::OkStatus();
  }

  absl::Status read_id(const json& root, const Path& top, Scenario* s) {
    const json* name = nullptr;
    const std::string* name_str = nullptr;
    const Path name_path = top.field("name");
    if (auto st = require(root, top, "name", &name); !st.ok()) return st;
    if (auto st = string(*name, name_path, &name_str); !st.ok()) return st;
    if (const json* sid = member(root, "scenario_id")) {
      const Path sid_path = top.field("scenario_id");
      const std::string* sid_str = nullptr;
      if (auto st = string(*sid, sid_path, &sid_str); !st.ok()) return st;
      if (sid_str->empty()) return fail(sid_path, "is empty");
      s->id = *sid_str;
      return absl::OkStatus();
    }
    std::string_view id = *name_str;
    if (id.size() >= 5 && id.substr(id.size() - 5) == ".json") id.remove_suffix(5);
    if (id.empty()) return fail(name_path, "is empty and there is no scenario_id: the scenario has no id");
    s->id = std::string(id);
    return absl::OkStatus();
  }

  // Requires obj[name] (at `p`) to be an array with one entry per frame; the first such array sets the frame count.
  absl::Status frame_array(const json& obj, const Path& obj_path, std::string_view name, const json** out,
                           const Path& p) {
    if (auto st = require(obj, obj_path, name, out); !st.ok()) return st;
    if (auto st = expect(**out, p, json::value_t::array); !st.ok()) return st;
    size_t n = (*out)->size();
    if (frames_ < 0) {
      frames_ = static_cast<int64_t>(n);
      frames_source_ = p.str();
      if (frames_ <= kCurrentTimeIndex)
        return fail(p, absl::StrCat("has ", n, " frames; a scenario needs at least ", kCurrentTimeIndex + 1,
                                    " (the current frame is ", kCurrentTimeIndex, ")"));
    } else if (static_cast<int64_t>(n) != frames_) {
      return fail(p, absl::StrCat("has ", n, " entries, but ", frames_source_, " has ", frames_,
                                  ": every per-frame array must have one entry per frame"));
    }
    return absl::OkStatus();
  }

  absl::Status read_objects(const json& root, const Path& top, Scenario* s) {
    const json* objects = nullptr;
    const Path objects_path = top.field("objects");
    if (auto st = require(root, top, "objects", &objects); !st.ok()) return st;
    if (auto st = expect(*objects, objects_path, json::value_t::array); !st.ok()) return st;
    if (objects->empty()) return fail(objects_path, "is empty: the frame count comes from the objects");

    // The heading unit is a property of the converter that wrote the file, told apart by the presence of ids.
    const bool radians = member((*objects)[0], "id") != nullptr || !(*objects)[0].is_object();
    std::unordered_set<int32_t> ids;
    s->tracks.reserve(objects->size());
    for (size_t i = 0; i < objects->size(); ++i) {
      const json& o = (*objects)[i];
      const Path op = objects_path.index(i);
      if (auto st = expect(o, op, json::value_t::object); !st.ok()) return st;
      Track tr;

      const json* id = member(o, "id");
      if ((id != nullptr) != radians)
        return fail(op, absl::StrCat(id ? "has" : "has no", " \"id\" but objects[0] ", id ? "has none" : "has one",
                                     ": the heading unit (radians with ids, degrees without) is ambiguous"));
      if (id) {
        int64_t v = 0;
        const Path idp = op.field("id");
        if (auto st = integer(*id, idp, std::numeric_limits<int32_t>::min(), std::numeric_limits<int32_t>::max(),
                              &v);
            !st.ok())
          return st;
        tr.id = static_cast<int32_t>(v);
      } else {
        if (i > static_cast<size_t>(std::numeric_limits<int32_t>::max())) return fail(op, "too many objects");
        tr.id = static_cast<int32_t>(i);
      }
      if (!ids.insert(tr.id).second) return fail(op.field("id"), absl::StrCat(tr.id, " is used by an earlier object"));

      const json* type = nullptr;
      const std::string* type_str = nullptr;
      const Path tp = op.field("type");
      if (auto st = require(o, op, "type", &type); !st.ok()) return st;
      if (auto st = string(*type, tp, &type_str); !st.ok()) return st;
      bool ok = false;
      tr.type = object_type_from(*type_str, &ok);
      if (!ok)
        return fail(tp, absl::StrCat("unknown object type ", quote_user(*type_str),
                                     " (expected vehicle, pedestrian, cyclist, unset or other)"));

      float size[3] = {0, 0, default_height(tr.type)};
      const char* size_names[] = {"length", "width", "height"};
      for (int k = 0; k < 3; ++k) {
        const json* v = member(o, size_names[k]);
        const Path sp = op.field(size_names[k]);
        if (!v) {
          if (k == 2) continue;  // older files have no height
          return fail(op, absl::StrCat("missing required key \"", size_names[k], "\""));
        }
        if (auto st = real_float(*v, sp, &size[k]); !st.ok()) return st;
        if (size[k] < 0) return fail(sp, absl::StrCat("is negative (", size[k], ")"));
      }

      const json *pos = nullptr, *heading = nullptr, *vel = nullptr, *valid = nullptr;
      const Path pp = op.field("position"), hp = op.field("heading"), vp = op.field("velocity"),
                 vap = op.field("valid");
      if (auto st = frame_array(o, op, "position", &pos, pp); !st.ok()) return st;
      if (auto st = frame_array(o, op, "heading", &heading, hp); !st.ok()) return st;
      if (auto st = frame_array(o, op, "velocity", &vel, vp); !st.ok()) return st;
      if (auto st = frame_array(o, op, "valid", &valid, vap); !st.ok()) return st;

      tr.states.resize(static_cast<size_t>(frames_));
      for (size_t f = 0; f < tr.states.size(); ++f) {
        const Path pfp = pp.index(f), hfp = hp.index(f), vfp = vp.index(f), vafp = vap.index(f);
        bool is_valid = false;
        if (auto st = boolean((*valid)[f], vafp, &is_valid); !st.ok()) return st;
        MapPoint c;
        if (auto st = point((*pos)[f], pfp, is_valid, &c); !st.ok()) return st;
        double h = 0;
        if (auto st = is_valid ? real_number((*heading)[f], hfp, &h) : number((*heading)[f], hfp, &h); !st.ok())
          return st;
        const json& vf = (*vel)[f];
        if (auto st = expect(vf, vfp, json::value_t::object); !st.ok()) return st;
        float v2[2] = {0, 0};
        const char* vnames[] = {"x", "y"};
        for (int k = 0; k < 2; ++k) {
          const json* c2 = member(vf, vnames[k]);
          const Path cp = vfp.field(vnames[k]);
          if (!c2) return fail(vfp, absl::StrCat("missing required key \"", vnames[k], "\""));
          double d = 0;
          if (!is_valid) {
            if (auto st = number(*c2, cp, &d); !st.ok()) return st;
          } else if (auto st = real_float(*c2, cp, &v2[k]); !st.ok()) {
            return st;
          }
        }
        if (!is_valid) continue;  // placeholders: keep the default state
        ObjectState& os = tr.states[f];
        os.x = c.x;
        os.y = c.y;
        os.z = c.z;
        os.length = size[0];
        os.width = size[1];
        os.height = size[2];
        os.heading = static_cast<float>(wrap_angle(radians ? h : h * (kPi / 180.0)));
        // A double just below pi can round up to float(pi) > pi; keep the [-pi, pi) convention in float too.
        if (os.heading >= static_cast<float>(kPi)) os.heading = -static_cast<float>(kPi);
        os.vx = v2[0];
        os.vy = v2[1];
        os.valid = true;
      }
      s->tracks.push_back(std::move(tr));
    }

    s->timestamps.resize(static_cast<size_t>(frames_));
    for (size_t f = 0; f < s->timestamps.size(); ++f) s->timestamps[f] = static_cast<double>(f) / 10.0;
    s->current_time_index = kCurrentTimeIndex;
    return absl::OkStatus();
  }

  absl::Status read_roads(const json& root, const Path& top, Scenario* s) {
    const json* roads = nullptr;
    const Path roads_path = top.field("roads");
    if (auto st = require(root, top, "roads", &roads); !st.ok()) return st;
    if (auto st = expect(*roads, roads_path, json::value_t::array); !st.ok()) return st;
    std::unordered_set<int64_t> ids;
    s->map_features.reserve(roads->size());
    for (size_t i = 0; i < roads->size(); ++i) {
      const json& r = (*roads)[i];
      const Path rp = roads_path.index(i);
      if (auto st = expect(r, rp, json::value_t::object); !st.ok()) return st;
      MapFeature mf;

      const json* type = nullptr;
      const std::string* type_str = nullptr;
      const Path tp = rp.field("type");
      if (auto st = require(r, rp, "type", &type); !st.ok()) return st;
      if (auto st = string(*type, tp, &type_str); !st.ok()) return st;
      std::optional<MapFeatureKind> kind = map_kind_from(*type_str);
      if (!kind)
        return fail(tp, absl::StrCat("unknown road type ", quote_user(*type_str),
                                     " (expected lane, road_line, road_edge, stop_sign, crosswalk, speed_bump or "
                                     "driveway)"));
      mf.kind = *kind;

      if (const json* meid = member(r, "map_element_id")) {
        const Path mp = rp.field("map_element_id");
        int64_t m = 0;
        if (auto st = integer(*meid, mp, -1, 20, &m); !st.ok()) return st;
        if (m != -1) {
          auto el = map_element_from(m);
          if (!el) return fail(mp, absl::StrCat(m, " is not a GPUDrive MapElementId (-1, 0..3, 5..20)"));
          if (el->first != mf.kind)
            return fail(mp, absl::StrCat(m, " denotes a ", map_feature_kind_name(el->first), ", but type is ",
                                         quote_user(*type_str)));
          mf.subtype = el->second;
        }
      }

      if (const json* id = member(r, "id")) {
        const Path ip = rp.field("id");
        if (auto st = integer(*id, ip, std::numeric_limits<int64_t>::min(), std::numeric_limits<int64_t>::max(),
                              &mf.id);
            !st.ok())
          return st;
      } else {
        mf.id = static_cast<int64_t>(i);
      }
      if (!ids.insert(mf.id).second)
        return fail(rp, absl::StrCat("map feature id ", mf.id, " is used by an earlier road"));

      const json* geom = nullptr;
      const Path gp = rp.field("geometry");
      if (auto st = require(r, rp, "geometry", &geom); !st.ok()) return st;
      if (auto st = expect(*geom, gp, json::value_t::array); !st.ok()) return st;
      if (geom->empty()) return fail(gp, "is empty");
      mf.points.resize(geom->size());
      for (size_t k = 0; k < geom->size(); ++k) {
        const Path kp = gp.index(k);
        if (auto st = point((*geom)[k], kp, false, &mf.points[k]); !st.ok()) return st;
      }
      const bool polygon = mf.kind == MapFeatureKind::crosswalk || mf.kind == MapFeatureKind::speed_bump ||
                           mf.kind == MapFeatureKind::driveway;
      if (polygon && mf.points.size() >= 2 && mf.points.front() == mf.points.back()) mf.points.pop_back();
      if (mf.kind == MapFeatureKind::stop_sign && mf.points.size() != 1)
        return fail(gp, absl::StrCat("a stop sign has one point (its position), got ", mf.points.size()));
      s->map_features.push_back(std::move(mf));
    }
    return absl::OkStatus();
  }

  absl::Status read_lights(const json& root, const Path& top, Scenario* s) {
    const json* tl = member(root, "tl_states");
    if (!tl) return absl::OkStatus();  // absent = no lights
    const Path tlp = top.field("tl_states");
    if (auto st = expect(*tl, tlp, json::value_t::object); !st.ok()) return st;

    std::vector<std::vector<SignalLaneState>> signals(static_cast<size_t>(frames_));
    bool any = false;
    for (const auto& [key, entry] : tl->get_ref<const json::object_t&>()) {
      const Path lp = tlp.key(key);
      int64_t lane = 0;
      auto [end, ec] = std::from_chars(key.data(), key.data() + key.size(), lane);
      // Only the canonical spelling, so two keys cannot name the same lane ("7" and "07").
      if (ec != std::errc() || end != key.data() + key.size() || std::to_string(lane) != key)
        return fail(lp, "key is not a lane id (a decimal integer such as \"123\")");
      if (auto st = expect(entry, lp, json::value_t::object); !st.ok()) return st;

      const json *state = nullptr, *x = nullptr, *y = nullptr, *ti = nullptr;
      const Path sp = lp.field("state"), xp = lp.field("x"), yp = lp.field("y"), zp = lp.field("z"),
                 tip = lp.field("time_index"), lip = lp.field("lane_id");
      const std::pair<std::string_view, const json**> required[] = {
          {"state", &state}, {"x", &x}, {"y", &y}, {"time_index", &ti}};
      for (const auto& [name, out] : required) {
        if (auto st = require(entry, lp, name, out); !st.ok()) return st;
        const Path np = lp.field(name);
        if (auto st = expect(**out, np, json::value_t::array); !st.ok()) return st;
      }
      const json* z = member(entry, "z");
      const json* lane_ids = member(entry, "lane_id");
      const size_t n = state->size();
      const std::pair<const json*, const Path*> arrays[] = {{x, &xp}, {y, &yp}, {ti, &tip}, {z, &zp}, {lane_ids, &lip}};
      for (const auto& [arr, ap] : arrays) {
        if (!arr) continue;
        if (auto st = expect(*arr, *ap, json::value_t::array); !st.ok()) return st;
        if (arr->size() != n)
          return fail(*ap, absl::StrCat("has ", arr->size(), " entries, but state has ", n));
      }

      // A set, not a per-frame bitmap: many lanes times many frames must not cost more than the input's size.
      std::unordered_set<int64_t> seen;
      seen.reserve(n);
      for (size_t k = 0; k < n; ++k) {
        const Path skp = sp.index(k), tkp = tip.index(k), xkp = xp.index(k), ykp = yp.index(k), zkp = zp.index(k),
                   lkp = lip.index(k);
        const std::string* name = nullptr;
        if (auto st = string((*state)[k], skp, &name); !st.ok()) return st;
        std::optional<SignalState> ss = signal_state_from(*name);
        if (!ss)
          return fail(skp, absl::StrCat("unknown light state ", quote_user(*name),
                                        " (expected unknown, arrow_stop, arrow_caution, arrow_go, stop, caution, go, "
                                        "flashing_stop or flashing_caution)"));
        int64_t frame = 0;
        if (auto st = integer((*ti)[k], tkp, 0, frames_ - 1, &frame); !st.ok()) return st;
        if (!seen.insert(frame).second)
          return fail(tkp, absl::StrCat("frame ", frame, " appears twice for this lane"));
        if (lane_ids) {
          int64_t l = 0;
          if (auto st = integer((*lane_ids)[k], lkp, std::numeric_limits<int64_t>::min(),
                                std::numeric_limits<int64_t>::max(), &l);
              !st.ok())
            return st;
          if (l != lane) return fail(lkp, absl::StrCat(l, " differs from the key's lane id ", lane));
        }
        SignalLaneState ls;
        ls.lane = lane;
        ls.state = *ss;
        ls.has_stop_point = true;
        if (auto st = real_number((*x)[k], xkp, &ls.stop_point.x); !st.ok()) return st;
        if (auto st = real_number((*y)[k], ykp, &ls.stop_point.y); !st.ok()) return st;
        if (z)
          if (auto st = real_number((*z)[k], zkp, &ls.stop_point.z); !st.ok()) return st;
        signals[static_cast<size_t>(frame)].push_back(ls);
        any = true;
      }
    }
    if (!any) return absl::OkStatus();
    for (auto& frame : signals)
      std::sort(frame.begin(), frame.end(), [](const auto& a, const auto& b) { return a.lane < b.lane; });
    s->signals = std::move(signals);
    return absl::OkStatus();
  }

  absl::Status read_metadata(const json& root, const Path& top, Scenario* s) {
    const json* md = member(root, "metadata");
    if (!md) return absl::OkStatus();
    const Path mp = top.field("metadata");
    if (auto st = expect(*md, mp, json::value_t::object); !st.ok()) return st;
    const int64_t n = static_cast<int64_t>(s->tracks.size());

    if (const json* sdc = member(*md, "sdc_track_index")) {
      const Path p = mp.field("sdc_track_index");
      int64_t v = 0;
      if (auto st = integer(*sdc, p, -1, n - 1, &v); !st.ok()) return st;
      s->sdc_track_index = static_cast<int32_t>(v);
    }

    if (const json* ooi = member(*md, "objects_of_interest")) {
      const Path p = mp.field("objects_of_interest");
      if (auto st = expect(*ooi, p, json::value_t::array); !st.ok()) return st;
      std::unordered_set<int32_t> ids;
      for (const Track& t : s->tracks) ids.insert(t.id);
      for (size_t k = 0; k < ooi->size(); ++k) {
        const Path kp = p.index(k);
        int64_t v = 0;
        if (auto st = integer((*ooi)[k], kp, std::numeric_limits<int32_t>::min(),
                              std::numeric_limits<int32_t>::max(), &v);
            !st.ok())
          return st;
        if (!ids.count(static_cast<int32_t>(v))) return fail(kp, absl::StrCat(v, " is not the id of an object"));
        s->objects_of_interest.push_back(static_cast<int32_t>(v));
      }
    }

    if (const json* ttp = member(*md, "tracks_to_predict")) {
      const Path p = mp.field("tracks_to_predict");
      if (auto st = expect(*ttp, p, json::value_t::array); !st.ok()) return st;
      for (size_t k = 0; k < ttp->size(); ++k) {
        const Path kp = p.index(k);
        const json& e = (*ttp)[k];
        if (auto st = expect(e, kp, json::value_t::object); !st.ok()) return st;
        const json *ti = nullptr, *diff = nullptr;
        const Path tip = kp.field("track_index"), dp = kp.field("difficulty");
        if (auto st = require(e, kp, "track_index", &ti); !st.ok()) return st;
        RequiredPrediction rp;
        int64_t v = 0;
        if (auto st = integer(*ti, tip, 0, n - 1, &v); !st.ok()) return st;
        rp.track_index = static_cast<int32_t>(v);
        if ((diff = member(e, "difficulty"))) {
          if (auto st = integer(*diff, dp, 0, 2, &v); !st.ok()) return st;
          rp.difficulty = static_cast<int32_t>(v);
        }
        s->tracks_to_predict.push_back(rp);
      }
    }
    return absl::OkStatus();
  }

  const std::string& where_;
  int64_t frames_ = -1;        // set by the first per-frame array read
  std::string frames_source_;  // that array's path, for length-mismatch messages
};

}  // namespace

absl::StatusOr<Scenario> scenario_from_gpudrive_json(std::string_view text, const std::string& where) {
  try {
    // The format needs 5 levels (root / objects / object / position / point); the limit keeps hostile input from
    // building deep trees (recursive destruction, recursive error paths).
    auto root = json_parse_strict(text, {.max_depth = 32});
    if (!root.ok()) return absl::Status(root.status().code(), absl::StrCat(where, ": ", root.status().message()));
    return Converter(where).convert(*root);
  } catch (const std::bad_alloc&) {
    // Sizes in the input are bounded by its length, so this means the input is too big for this machine.
    return absl::ResourceExhaustedError(absl::StrCat(where, ": out of memory reading ", text.size(), " bytes"));
  }
}

}  // namespace ss
