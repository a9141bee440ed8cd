#include "offline/eval/submission.h"

#include <algorithm>
#include <cstdio>
#include <cmath>
#include <filesystem>
#include <map>
#include <regex>
#include <set>

#include "absl/strings/str_cat.h"
#include "offline/eval/baselines.h"
#include "engine/io/file_io.h"
#include "engine/io/json_strict.h"
#include "nlohmann/json.hpp"
#include "womd/sim_agents_submission.pb.h"

namespace ss {
namespace {

namespace wo = waymo::open_dataset;
namespace fs = std::filesystem;

const Track* track_by_id(const Scenario& s, int64_t id) {
  for (const Track& t : s.tracks)
    if (t.id == id) return &t;
  return nullptr;
}

// "-00003-of-00010": the challenge's shard numbering.
std::string shard_suffix(int shard, int shards) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "-%05d-of-%05d", shard, shards);
  return buf;
}

bool all_finite(const SimulatedTrajectory& t) {
  for (const std::vector<float>* v : {&t.x, &t.y, &t.z, &t.heading, &t.length, &t.width, &t.height})
    for (float f : *v)
      if (!std::isfinite(f)) return false;
  return true;
}

}  // namespace

absl::StatusOr<SubmissionMetadata> read_submission_metadata(const std::string& path) {
  auto bytes = file_read_all(path);
  if (!bytes.ok()) return bytes.status();
  auto parsed = json_parse_strict(*bytes);
  if (!parsed.ok()) return absl::Status(parsed.status().code(), absl::StrCat(path, ": ", parsed.status().message()));
  const nlohmann::json& j = *parsed;
  if (!j.is_object()) return absl::InvalidArgumentError(absl::StrCat(path, ": submission metadata is not a JSON object"));
  SubmissionMetadata m;
  const std::map<std::string, std::string*> strings = {
      {"account_name", &m.account_name},     {"unique_method_name", &m.unique_method_name},
      {"affiliation", &m.affiliation},       {"description", &m.description},
      {"method_link", &m.method_link},       {"num_model_parameters", &m.num_model_parameters}};
  const std::map<std::string, std::vector<std::string>*> lists = {{"authors", &m.authors},
                                                                  {"public_model_names", &m.public_model_names}};
  const std::map<std::string, bool*> flags = {
      {"uses_lidar_data", &m.uses_lidar_data},
      {"uses_camera_data", &m.uses_camera_data},
      {"uses_public_model_pretraining", &m.uses_public_model_pretraining},
      {"acknowledge_complies_with_closed_loop_requirement", &m.acknowledge_complies_with_closed_loop_requirement}};
  for (const auto& item : j.items()) {
    // Named copies, not a structured binding: clang 14 (the fuzz build) cannot capture bindings in a lambda.
    const std::string& key = item.key();
    const auto& value = item.value();
    auto wrong = [&](const char* type) {
      return absl::InvalidArgumentError(absl::StrCat(path, ": \"", key, "\" must be ", type));
    };
    if (auto s = strings.find(key); s != strings.end()) {
      if (!value.is_string()) return wrong("a string");
      *s->second = value.get<std::string>();
    } else if (auto l = lists.find(key); l != lists.end()) {
      if (!value.is_array() || !std::all_of(value.begin(), value.end(), [](const auto& v) { return v.is_string(); }))
        return wrong("a list of strings");
      *l->second = value.get<std::vector<std::string>>();
    } else if (auto b = flags.find(key); b != flags.end()) {
      if (!value.is_boolean()) return wrong("true or false");
      *b->second = value.get<bool>();
    } else {
      return absl::InvalidArgumentError(absl::StrCat(path, ": unknown key \"", key,
                                                     "\" (keys are the fields of SimAgentsChallengeSubmission)"));
    }
  }
  return m;
}

namespace {

// Rollouts as the submission holds them. Sim agents: at least the sim agents, the frames after the current one, the
// pose only. Scenario generation (`scene_gen`): exactly the sim agents, every frame, with type, box and validity.
absl::StatusOr<ScenarioRollouts> submission_rollouts(const Scenario& s, const std::vector<JointScene>& scenes,
                                                     bool scene_gen) {
  const int first_frame = scene_gen ? 0 : s.current_time_index + 1;
  const std::vector<int> agents = sim_agent_tracks(s);
  ScenarioRollouts out;
  out.scenario_id = s.id;
  for (size_t r = 0; r < scenes.size(); ++r) {
    const JointScene& scene = scenes[r];
    const bool count_ok = scene_gen ? scene.objects.size() == agents.size() : scene.objects.size() >= agents.size();
    if (!count_ok || scene.num_frames() != s.num_frames())
      return absl::InvalidArgumentError(absl::StrCat("scenario ", s.id, " rollout ", r, ": ", scene.objects.size(),
                                                     " objects over ", scene.num_frames(), " frames, not the ",
                                                     agents.size(), " sim agents over ", s.num_frames()));
    std::vector<SimulatedTrajectory> joint;
    for (size_t k = 0; k < agents.size(); ++k) {
      const SceneObject& o = scene.objects[k];
      if (o.id != s.tracks[agents[k]].id)
        return absl::InvalidArgumentError(absl::StrCat("scenario ", s.id, " rollout ", r, ": object ", k, " is ", o.id,
                                                       ", not sim agent ", s.tracks[agents[k]].id));
      SimulatedTrajectory t;
      t.object_id = static_cast<int32_t>(o.id);
      if (scene_gen) t.object_type = static_cast<int32_t>(o.type);
      const int end = scene_gen ? static_cast<int>(o.states.size()) : scene.num_frames();
      for (int f = first_frame; f < end; ++f) {
        const BoxState& b = o.states[f];
        if (!b.valid)
          return absl::InvalidArgumentError(absl::StrCat(
              "scenario ", s.id, " rollout ", r, ": object ", o.id, " has no state at frame ", f,
              scene_gen ? ", and a scenario-generation submission holds every frame"
                        : ", and a submission holds every sim agent at every frame"));
        for (auto [v, x] : {std::pair{&t.x, b.x}, {&t.y, b.y}, {&t.z, b.z}, {&t.heading, b.heading}})
          v->push_back(static_cast<float>(x));
        if (!scene_gen) continue;
        for (auto [v, x] : {std::pair{&t.length, b.length}, {&t.width, b.width}, {&t.height, b.height}})
          v->push_back(static_cast<float>(x));
        t.valid.push_back(1);
      }
      joint.push_back(std::move(t));
    }
    out.joint_scenes.push_back(std::move(joint));
  }
  return out;
}

}  // namespace

absl::StatusOr<ScenarioRollouts> rollouts_from_scenes(const Scenario& s, const std::vector<JointScene>& scenes) {
  return submission_rollouts(s, scenes, /*scene_gen=*/false);
}

std::vector<SimulatedTrajectory> trajectories_from_rollout(const Scenario& rollout) {
  const int now = rollout.current_time_index;
  const std::vector<int> agents = sim_agent_tracks(rollout);
  JointScene scene = log_scene(rollout, agents);
  std::vector<SimulatedTrajectory> out;
  for (size_t k = 0; k < agents.size(); ++k) {
    const Track& t = rollout.tracks[agents[k]];
    std::vector<BoxState>& st = scene.objects[k].states;
    int last = now;
    while (last + 1 < rollout.num_frames() && t.states[last + 1].valid) ++last;
    extend_constant_velocity(st, last, t.states[last].vx, t.states[last].vy);
    SimulatedTrajectory traj;
    traj.object_id = t.id;
    for (int f = now + 1; f < rollout.num_frames(); ++f) {
      traj.x.push_back(static_cast<float>(st[f].x));
      traj.y.push_back(static_cast<float>(st[f].y));
      traj.z.push_back(static_cast<float>(st[f].z));
      traj.heading.push_back(static_cast<float>(st[f].heading));
    }
    out.push_back(std::move(traj));
  }
  return out;
}

void round_to_submission(JointScene& scene, int now) {
  // Through a volatile float: GCC 12 (-O2, AVX) vectorizes two neighbouring double -> float -> double round trips
  // and then folds the pair of conversions away, leaving the values unrounded (measured: the function compiled to a
  // bare `ret`).
  auto to_float = [](double v) {
    volatile float f = static_cast<float>(v);
    return static_cast<double>(f);
  };
  for (SceneObject& o : scene.objects)
    for (size_t f = now + 1; f < o.states.size(); ++f) {
      BoxState& b = o.states[f];
      b.x = to_float(b.x), b.y = to_float(b.y), b.z = to_float(b.z), b.heading = to_float(b.heading);
    }
}

absl::StatusOr<std::vector<JointScene>> scenes_from_rollouts(const Scenario& s, const ScenarioRollouts& r,
                                                             const std::string& where) {
  const int now = s.current_time_index;
  const int future = s.num_frames() - 1 - now;
  const std::vector<int> agents = sim_agent_tracks(s);
  std::map<int64_t, size_t> index;  // object id -> position among the sim agents
  for (size_t k = 0; k < agents.size(); ++k) index[s.tracks[agents[k]].id] = k;
  if (r.joint_scenes.empty()) return absl::InvalidArgumentError(absl::StrCat(where, ": scenario ", s.id, " has no rollout"));
  const JointScene log = log_scene(s, agents);
  std::vector<JointScene> out;
  for (size_t n = 0; n < r.joint_scenes.size(); ++n) {
    const std::string at = absl::StrCat(where, ": scenario ", s.id, " rollout ", n);
    JointScene scene = log;
    std::vector<bool> seen(agents.size(), false);
    for (const SimulatedTrajectory& t : r.joint_scenes[n]) {
      auto it = index.find(t.object_id);
      if (it == index.end())
        return absl::InvalidArgumentError(absl::StrCat(
            at, ": object ", t.object_id,
            track_by_id(s, t.object_id) ? " is not valid at the current frame, so it is not a sim agent"
                                        : " is not in the scenario"));
      if (seen[it->second])
        return absl::InvalidArgumentError(absl::StrCat(at, ": object ", t.object_id, " is given twice"));
      seen[it->second] = true;
      const std::pair<const char*, const std::vector<float>*> fields[] = {
          {"center_x", &t.x}, {"center_y", &t.y}, {"center_z", &t.z}, {"heading", &t.heading}};
      for (const auto& [name, v] : fields)
        if (static_cast<int>(v->size()) != future)
          return absl::InvalidArgumentError(absl::StrCat(at, ": object ", t.object_id, " has ", v->size(), " ", name,
                                                         " values; the scenario has ", future,
                                                         " frames after its current frame ", now));
      if (!all_finite(t))
        return absl::InvalidArgumentError(absl::StrCat(at, ": object ", t.object_id, " has a non-finite value"));
      std::vector<BoxState>& st = scene.objects[it->second].states;
      const BoxState held = st[now];
      for (int j = 0; j < future; ++j)
        st[now + 1 + j] = {t.x[j], t.y[j], t.z[j], t.heading[j], held.length, held.width, held.height, true};
    }
    for (size_t k = 0; k < agents.size(); ++k)
      if (!seen[k])
        return absl::InvalidArgumentError(absl::StrCat(at, ": sim agent ", s.tracks[agents[k]].id,
                                                       " (valid at the current frame) is missing"));
    out.push_back(std::move(scene));
  }
  return out;
}

absl::StatusOr<ScenarioRollouts> scenegen_rollouts_from_scenes(const Scenario& s, const std::vector<JointScene>& scenes) {
  return submission_rollouts(s, scenes, /*scene_gen=*/true);
}

absl::StatusOr<std::vector<JointScene>> scenegen_scenes_from_rollouts(const Scenario& s, const ScenarioRollouts& r,
                                                                      const std::string& where) {
  const int frames = s.num_frames();
  const std::vector<int> agents = sim_agent_tracks(s);
  std::map<int64_t, size_t> index;
  for (size_t k = 0; k < agents.size(); ++k) index[s.tracks[agents[k]].id] = k;
  if (r.joint_scenes.empty()) return absl::InvalidArgumentError(absl::StrCat(where, ": scenario ", s.id, " has no rollout"));
  std::vector<JointScene> out;
  for (size_t n = 0; n < r.joint_scenes.size(); ++n) {
    const std::string at = absl::StrCat(where, ": scenario ", s.id, " rollout ", n);
    JointScene scene;
    scene.objects.resize(agents.size());
    std::vector<bool> seen(agents.size(), false);
    for (const SimulatedTrajectory& t : r.joint_scenes[n]) {
      auto it = index.find(t.object_id);
      if (it == index.end())
        return absl::InvalidArgumentError(absl::StrCat(
            at, ": object ", t.object_id,
            track_by_id(s, t.object_id) ? " is not valid at the current frame, so it is not a sim agent"
                                        : " is not in the scenario"));
      if (seen[it->second])
        return absl::InvalidArgumentError(absl::StrCat(at, ": object ", t.object_id, " is given twice"));
      seen[it->second] = true;
      const std::pair<const char*, size_t> fields[] = {
          {"center_x", t.x.size()},       {"center_y", t.y.size()},     {"center_z", t.z.size()},
          {"heading", t.heading.size()},  {"length", t.length.size()},  {"width", t.width.size()},
          {"height", t.height.size()},    {"valid", t.valid.size()}};
      for (const auto& [name, size] : fields)
        if (static_cast<int>(size) != frames)
          return absl::InvalidArgumentError(absl::StrCat(at, ": object ", t.object_id, " has ", size, " ", name,
                                                         " values; a scenario-generation trajectory has one per frame (",
                                                         frames, ")"));
      if (!all_finite(t))
        return absl::InvalidArgumentError(absl::StrCat(at, ": object ", t.object_id, " has a non-finite value"));
      const ObjectType type = static_cast<ObjectType>(t.object_type);
      if (type != ObjectType::vehicle && type != ObjectType::pedestrian && type != ObjectType::cyclist)
        return absl::InvalidArgumentError(absl::StrCat(at, ": object ", t.object_id, " has object_type ", t.object_type,
                                                       "; a generated agent is a vehicle (1), pedestrian (2) or cyclist (3)"));
      SceneObject& o = scene.objects[it->second];
      o.id = t.object_id;
      o.type = type;
      for (int f = 0; f < frames; ++f)
        o.states.push_back({t.x[f], t.y[f], t.z[f], t.heading[f], t.length[f], t.width[f], t.height[f], true});
    }
    for (size_t k = 0; k < agents.size(); ++k)
      if (!seen[k])
        return absl::InvalidArgumentError(absl::StrCat(at, ": sim agent ", s.tracks[agents[k]].id,
                                                       " (valid at the current frame) is missing"));
    out.push_back(std::move(scene));
  }
  return out;
}

std::vector<std::string> challenge_problems(const std::vector<ScenarioRollouts>& rollouts,
                                            const std::vector<const Scenario*>& scenarios,
                                            const SubmissionMetadata& m) {
  std::vector<std::string> out;
  std::map<std::string, const Scenario*> by_id;
  for (const Scenario* s : scenarios) by_id[s->id] = s;
  int wrong_count = 0, wrong_shape = 0;
  std::string count_example, shape_example;
  for (const ScenarioRollouts& r : rollouts) {
    if (r.joint_scenes.size() != kChallengeRollouts && wrong_count++ == 0)
      count_example = absl::StrCat(r.scenario_id, " has ", r.joint_scenes.size());
    auto it = by_id.find(r.scenario_id);
    if (it == by_id.end()) continue;
    const Scenario& s = *it->second;
    if ((s.current_time_index != kChallengeCurrentFrame ||
         s.num_frames() - 1 - s.current_time_index != kChallengeFutureFrames) &&
        wrong_shape++ == 0)
      shape_example = absl::StrCat(s.id, ": current frame ", s.current_time_index, ", ",
                                   s.num_frames() - 1 - s.current_time_index, " after it");
  }
  if (wrong_count)
    out.push_back(absl::StrCat(wrong_count, " scenario(s) do not have ", kChallengeRollouts, " rollouts (",
                               count_example, ")"));
  if (wrong_shape)
    out.push_back(absl::StrCat(wrong_shape, " scenario(s) are not WOMD's current frame ", kChallengeCurrentFrame, " and ",
                               kChallengeFutureFrames, " frames after it (", shape_example, ")"));
  std::vector<std::string> missing;
  if (m.account_name.empty()) missing.push_back("account_name");
  if (m.unique_method_name.empty()) missing.push_back("unique_method_name");
  if (m.authors.empty()) missing.push_back("authors");
  if (m.affiliation.empty()) missing.push_back("affiliation");
  if (m.num_model_parameters.empty()) missing.push_back("num_model_parameters");
  if (!m.acknowledge_complies_with_closed_loop_requirement)
    missing.push_back("acknowledge_complies_with_closed_loop_requirement (read the challenge's rules first)");
  if (!missing.empty()) {
    std::string list;
    for (const std::string& k : missing) absl::StrAppend(&list, list.empty() ? "" : ", ", k);
    out.push_back(absl::StrCat("metadata the challenge requires is missing: ", list));
  }
  return out;
}

Scenario with_empty_future(const Scenario& s, int future_frames) {
  Scenario out = s;
  const int frames = s.num_frames() + future_frames;
  for (int j = 1; j <= future_frames; ++j) out.timestamps.push_back(s.timestamps.back() + j * kEvalFrameSeconds);
  for (Track& t : out.tracks) t.states.resize(frames);
  if (!out.signals.empty()) out.signals.resize(frames);
  return out;
}

std::string submission_shard_path(const std::string& dir, int shard, int shards) {
  return absl::StrCat(dir, "/submission.binproto", shard_suffix(shard, shards));
}

int submission_shard_count(int scenarios) { return std::max(1, (scenarios + kScenariosPerShard - 1) / kScenariosPerShard); }

absl::Status write_submission_shard(const std::string& path, const std::vector<ScenarioRollouts>& rollouts,
                                    const SubmissionMetadata& m) {
  wo::SimAgentsChallengeSubmission p;
  for (const ScenarioRollouts& r : rollouts) {
    wo::ScenarioRollouts* pr = p.add_scenario_rollouts();
    pr->set_scenario_id(r.scenario_id);
    for (const std::vector<SimulatedTrajectory>& joint : r.joint_scenes) {
      wo::JointScene* pj = pr->add_joint_scenes();
      for (const SimulatedTrajectory& t : joint) {
        wo::SimulatedTrajectory* pt = pj->add_simulated_trajectories();
        pt->mutable_center_x()->Add(t.x.begin(), t.x.end());
        pt->mutable_center_y()->Add(t.y.begin(), t.y.end());
        pt->mutable_center_z()->Add(t.z.begin(), t.z.end());
        pt->mutable_heading()->Add(t.heading.begin(), t.heading.end());
        pt->set_object_id(t.object_id);
        pt->mutable_length()->Add(t.length.begin(), t.length.end());
        pt->mutable_width()->Add(t.width.begin(), t.width.end());
        pt->mutable_height()->Add(t.height.begin(), t.height.end());
        for (uint8_t v : t.valid) pt->add_valid(v != 0);
        if (t.object_type != 0) pt->set_object_type(t.object_type);
      }
    }
  }
  p.set_submission_type(wo::SimAgentsChallengeSubmission::SIM_AGENTS_SUBMISSION);
  p.set_account_name(m.account_name);
  p.set_unique_method_name(m.unique_method_name);
  for (const std::string& a : m.authors) p.add_authors(a);
  p.set_affiliation(m.affiliation);
  p.set_description(m.description);
  p.set_method_link(m.method_link);
  p.set_uses_lidar_data(m.uses_lidar_data);
  p.set_uses_camera_data(m.uses_camera_data);
  p.set_uses_public_model_pretraining(m.uses_public_model_pretraining);
  for (const std::string& n : m.public_model_names) p.add_public_model_names(n);
  p.set_num_model_parameters(m.num_model_parameters);
  p.set_acknowledge_complies_with_closed_loop_requirement(m.acknowledge_complies_with_closed_loop_requirement);
  if (p.ByteSizeLong() > static_cast<size_t>(INT32_MAX))
    return absl::InvalidArgumentError(absl::StrCat(path, ": ", rollouts.size(),
                                                   " scenarios exceed protobuf's 2 GB message limit"));
  std::string bytes;
  if (!p.SerializeToString(&bytes)) return absl::InternalError(absl::StrCat(path, ": cannot serialize the submission"));
  return file_write_atomically(path, bytes);
}

absl::Status write_submission(const std::string& dir, const std::vector<ScenarioRollouts>& rollouts,
                              const SubmissionMetadata& metadata) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return absl::InternalError(absl::StrCat("cannot create ", dir, ": ", ec.message()));
  const int shards = submission_shard_count(static_cast<int>(rollouts.size()));
  for (int i = 0; i < shards; ++i) {
    const auto begin = rollouts.begin() + std::min<size_t>(rollouts.size(), i * size_t{kScenariosPerShard});
    const auto end = rollouts.begin() + std::min<size_t>(rollouts.size(), (i + 1) * size_t{kScenariosPerShard});
    if (auto st = write_submission_shard(submission_shard_path(dir, i, shards), {begin, end}, metadata); !st.ok())
      return st;
  }
  return absl::OkStatus();
}

absl::StatusOr<Submission> read_submission(const std::vector<std::string>& paths) {
  static const std::regex kShardName(R"(.*\.binproto(-(\d{5})-of-(\d{5}))?)");
  std::vector<std::string> files;
  for (const std::string& p : paths) {
    std::error_code ec;
    if (!fs::is_directory(p, ec)) {
      files.push_back(p);
      continue;
    }
    std::vector<std::string> in_dir;
    for (const fs::directory_entry& e : fs::directory_iterator(p, ec))
      if (e.is_regular_file() && std::regex_match(e.path().filename().string(), kShardName))
        in_dir.push_back(e.path().string());
    if (ec) return absl::InternalError(absl::StrCat("cannot list ", p, ": ", ec.message()));
    if (in_dir.empty())
      return absl::InvalidArgumentError(absl::StrCat(p, ": no submission files (NAME.binproto or NAME.binproto-00000-of-00001)"));
    std::sort(in_dir.begin(), in_dir.end());
    files.insert(files.end(), in_dir.begin(), in_dir.end());
  }
  // Numbered shards: every index of each "NAME.binproto-...-of-N" set must be there.
  std::map<std::pair<std::string, int>, std::set<int>> sets;
  for (const std::string& f : files) {
    std::smatch m;
    const std::string name = fs::path(f).filename().string();
    if (std::regex_match(name, m, kShardName) && m[1].matched)
      sets[{(fs::path(f).parent_path() / name.substr(0, m.position(1))).string(), std::stoi(m[3].str())}].insert(std::stoi(m[2].str()));
  }
  for (const auto& [key, have] : sets)
    for (int i = 0; i < key.second; ++i)
      if (!have.count(i))
        return absl::InvalidArgumentError(absl::StrCat(key.first, shard_suffix(i, key.second), " is missing (",
                                                       have.size(), " of ", key.second, " shards given)"));

  Submission out;
  std::set<std::string> ids;
  for (size_t n = 0; n < files.size(); ++n) {
    auto bytes = file_read_all(files[n]);
    if (!bytes.ok()) return bytes.status();
    wo::SimAgentsChallengeSubmission p;
    if (!p.ParseFromString(*bytes))
      return absl::InvalidArgumentError(absl::StrCat(files[n], ": not a SimAgentsChallengeSubmission proto"));
    if (p.submission_type() != wo::SimAgentsChallengeSubmission::SIM_AGENTS_SUBMISSION)
      return absl::InvalidArgumentError(absl::StrCat(files[n], ": submission_type is ",
                                                     wo::SimAgentsChallengeSubmission::SubmissionType_Name(p.submission_type()),
                                                     ", not SIM_AGENTS_SUBMISSION"));
    if (n == 0) {
      SubmissionMetadata& m = out.metadata;
      m.account_name = p.account_name(), m.unique_method_name = p.unique_method_name();
      m.authors.assign(p.authors().begin(), p.authors().end());
      m.affiliation = p.affiliation(), m.description = p.description(), m.method_link = p.method_link();
      m.uses_lidar_data = p.uses_lidar_data(), m.uses_camera_data = p.uses_camera_data();
      m.uses_public_model_pretraining = p.uses_public_model_pretraining();
      m.public_model_names.assign(p.public_model_names().begin(), p.public_model_names().end());
      m.num_model_parameters = p.num_model_parameters();
      m.acknowledge_complies_with_closed_loop_requirement = p.acknowledge_complies_with_closed_loop_requirement();
    }
    for (int i = 0; i < p.scenario_rollouts_size(); ++i) {
      const wo::ScenarioRollouts& pr = p.scenario_rollouts(i);
      if (!pr.has_scenario_id())
        return absl::InvalidArgumentError(absl::StrCat(files[n], ": scenario_rollouts[", i, "] has no scenario_id"));
      if (!ids.insert(pr.scenario_id()).second)
        return absl::InvalidArgumentError(absl::StrCat(files[n], ": scenario ", pr.scenario_id(), " is given twice"));
      ScenarioRollouts r;
      r.scenario_id = pr.scenario_id();
      for (const wo::JointScene& pj : pr.joint_scenes()) {
        std::vector<SimulatedTrajectory> joint;
        for (const wo::SimulatedTrajectory& pt : pj.simulated_trajectories())
          joint.push_back({pt.object_id(),
                           {pt.center_x().begin(), pt.center_x().end()},
                           {pt.center_y().begin(), pt.center_y().end()},
                           {pt.center_z().begin(), pt.center_z().end()},
                           {pt.heading().begin(), pt.heading().end()},
                           {pt.length().begin(), pt.length().end()},
                           {pt.width().begin(), pt.width().end()},
                           {pt.height().begin(), pt.height().end()},
                           {pt.valid().begin(), pt.valid().end()},
                           pt.object_type()});
        r.joint_scenes.push_back(std::move(joint));
      }
      out.rollouts.push_back(std::move(r));
    }
  }
  return out;
}

}  // namespace ss
