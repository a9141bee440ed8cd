#include "training/trainer.h"

#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>
#include <numbers>
#include <span>

#include <torch/torch.h>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "engine/model/model.h"
#include "engine/model/weights.h"
#include "training/teacher_forcing.h"
#include "training/batch.h"
#include "training/data.h"
#include "training/loss.h"
#include "training/model.h"

namespace ss::train {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop = true; }

// What the logs show: every head, then the end head at each sequence's first step alone (part of "end").
const char* kLogged[] = {"light", "motion", "type", "end", "segment", "state", "end0"};
const std::span<const char* const> kHeads(kLogged, 6);  // the heads whose losses the total sums

struct RunState {
  int64_t step = 0;
  DataCursor cursor;
  double elapsed = 0;  // seconds trained over every session of the run
};

double learning_rate(const TrainOptions& o, int64_t step) {
  if (step < o.warmup) return o.lr * (step + 1) / o.warmup;
  const double progress = std::min(1.0, static_cast<double>(step - o.warmup) / std::max<int64_t>(1, o.steps - o.warmup));
  return o.lr * (o.min_lr_ratio + (1 - o.min_lr_ratio) * 0.5 * (1 + std::cos(std::numbers::pi * progress)));
}

absl::Status save_checkpoint(const fs::path& path, const TorchModel& model, torch::optim::AdamW& opt,
                             const RunState& st, const std::string& config) {
  torch::serialize::OutputArchive archive;
  for (const auto& [name, t] : model.named_parameters()) archive.write("param/" + name, t.detach());
  torch::serialize::OutputArchive opt_archive;
  opt.save(opt_archive);
  archive.write("optimizer", opt_archive);
  archive.write("step", torch::tensor(st.step, torch::kInt64));
  archive.write("cursor", torch::tensor({st.cursor.samples, st.cursor.real, st.cursor.synthetic}, torch::kInt64));
  archive.write("elapsed", torch::tensor(st.elapsed, torch::kFloat64));
  archive.write("config_" + config, torch::tensor(1));
  const fs::path tmp = path.string() + ".tmp";
  try {
    archive.save_to(tmp.string());
  } catch (const std::exception& e) {
    return absl::InternalError(absl::StrCat("checkpoint ", tmp.string(), ": ", e.what()));
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) return absl::InternalError(absl::StrCat("checkpoint rename to ", path.string(), ": ", ec.message()));
  return absl::OkStatus();
}

absl::Status load_checkpoint(const fs::path& path, TorchModel& model, torch::optim::AdamW* opt, RunState& st,
                             const std::string& config) {
  torch::serialize::InputArchive archive;
  try {
    archive.load_from(path.string());
    torch::Tensor marker;
    if (!archive.try_read("config_" + config, marker))
      return absl::InvalidArgumentError(absl::StrCat("checkpoint ", path.string(), " is not of config ", config));
    torch::NoGradGuard no_grad;
    for (const auto& [name, t] : model.named_parameters()) {
      torch::Tensor v;
      archive.read("param/" + name, v);
      if (v.sizes() != t.sizes())
        return absl::InvalidArgumentError(absl::StrCat("checkpoint ", path.string(), ": ", name, " has the wrong shape"));
      const_cast<torch::Tensor&>(t).copy_(v);
    }
    if (opt) {
      torch::serialize::InputArchive opt_archive;
      archive.read("optimizer", opt_archive);
      opt->load(opt_archive);
    }
    torch::Tensor step, cursor, elapsed;
    archive.read("step", step);
    archive.read("cursor", cursor);
    archive.read("elapsed", elapsed);
    st.step = step.item<int64_t>();
    st.cursor = {cursor[0].item<int64_t>(), cursor[1].item<int64_t>(), cursor[2].item<int64_t>()};
    st.elapsed = elapsed.item<double>();
  } catch (const std::exception& e) {
    return absl::InvalidArgumentError(absl::StrCat("checkpoint ", path.string(), ": ", e.what()));
  }
  return absl::OkStatus();
}

TeacherForcingOptions example_options(const TrainOptions& o, int phase, uint64_t slot_seed) {
  TeacherForcingOptions t;
  t.phase = phase;
  t.max_agents = o.max_agents;
  t.max_map_segments = o.max_map_segments;
  t.slot_seed = slot_seed;
  return t;
}

// Accumulates head statistics over several batches, weighted by target counts.
struct StatSum {
  std::map<std::string, HeadStat> sum;
  void add(const Loss& l) {
    for (const auto& [name, s] : l.heads) {
      HeadStat& t = sum[name];
      t.loss += s.loss * s.count;
      t.accuracy += s.accuracy * s.count;
      t.count += s.count;
    }
  }
  HeadStat mean(const std::string& name) const {
    auto it = sum.find(name);
    if (it == sum.end() || it->second.count == 0) return {};
    return {it->second.loss / it->second.count, it->second.count, it->second.accuracy / it->second.count};
  }
};

std::string csv_header() {
  std::string h = "step,elapsed_s,lr,stage,tokens_per_s,loss";
  for (const char* n : kLogged) absl::StrAppend(&h, ",", n, "_loss,", n, "_acc");
  return h + "\n";
}

std::string csv_row(int64_t step, double elapsed, double lr, int stage, double tps, double total, const StatSum& s) {
  std::string r = absl::StrFormat("%d,%.1f,%.6g,%d,%.1f,%.5f", step, elapsed, lr, stage, tps, total);
  for (const char* n : kLogged) {
    const HeadStat h = s.mean(n);
    absl::StrAppendFormat(&r, ",%.5f,%.4f", h.loss, h.accuracy);
  }
  return r + "\n";
}

void append_line(const fs::path& path, const std::string& header, const std::string& line) {
  const bool fresh = !fs::exists(path);
  std::ofstream f(path, std::ios::app);
  if (fresh) f << header;
  f << line;
}

}  // namespace

absl::Status run_training(const TrainOptions& o) {
  auto config = model_config_by_name(o.config);
  if (!config.ok()) return config.status();
  if (o.out.empty()) return absl::InvalidArgumentError("--out is required");
  if (o.real_data.empty() && o.synthetic_data.empty()) return absl::InvalidArgumentError("no training data (--data)");
  if (o.batch < 1 || o.steps < 1 || o.warmup < 1 || o.lr <= 0 || o.threads < 1)
    return absl::InvalidArgumentError("--batch, --steps, --warmup, --lr and --threads must be positive");
  if (o.real_fraction < 0 || o.real_fraction > 1) return absl::InvalidArgumentError("--real-fraction must be in [0, 1]");
  if (o.catk_top_k < 0) return absl::InvalidArgumentError(absl::StrCat("--catk ", o.catk_top_k, " must be 0 (off) or positive"));
  if (!(o.scene_end_weight > 0) || !std::isfinite(o.scene_end_weight))
    return absl::InvalidArgumentError(absl::StrCat("--scene-end-weight ", o.scene_end_weight, " must be positive"));
  if (!(o.placement_weight > 0) || !std::isfinite(o.placement_weight))
    return absl::InvalidArgumentError(absl::StrCat("--placement-weight ", o.placement_weight, " must be positive"));
  torch::set_num_threads(o.threads);
  at::globalContext().setFlushDenormal(true);

  auto real = load_corpus(o.real_data);
  if (!real.ok()) return real.status();
  auto synthetic = load_corpus(o.synthetic_data);
  if (!synthetic.ok()) return synthetic.status();
  auto val = load_corpus(o.val_data);
  if (!val.ok()) return val.status();
  if (real->scenarios.empty() && synthetic->scenarios.empty())
    return absl::InvalidArgumentError("the training data paths hold no scenarios");
  for (const Scenario& v : val->scenarios)
    for (const Scenario& t : real->scenarios)
      if (!v.id.empty() && v.id == t.id)
        return absl::InvalidArgumentError(absl::StrCat("scenario ", v.id, " is in both the training and the val data"));
  std::printf("data: %zu real scenarios (%zu files), %zu synthetic (%zu files), %zu val; mix %.2f real\n",
              real->scenarios.size(), real->files.size(), synthetic->scenarios.size(), synthetic->files.size(),
              val->scenarios.size(), o.real_fraction);

  std::error_code ec;
  fs::create_directories(o.out, ec);
  if (ec) return absl::InvalidArgumentError(absl::StrCat("--out ", o.out, ": ", ec.message()));
  const fs::path dir(o.out), ckpt = dir / "checkpoint.pt";

  TorchModel model(init_weights(*config, o.seed));
  torch::optim::AdamW opt(model.parameters(), torch::optim::AdamWOptions(o.lr).betas({0.9, 0.95}).weight_decay(o.weight_decay));
  RunState st;
  if (o.resume && fs::exists(ckpt)) {
    if (auto s = load_checkpoint(ckpt, model, &opt, st, o.config); !s.ok()) return s;
    std::printf("resumed from %s at step %ld (%ld samples drawn, %.0f s trained)\n", ckpt.c_str(),
                static_cast<long>(st.step), static_cast<long>(st.cursor.samples), st.elapsed);
  } else if (fs::exists(ckpt)) {
    return absl::FailedPreconditionError(absl::StrCat(ckpt.string(), " exists: pass --resume, or another --out"));
  } else if (!o.init_from.empty()) {
    RunState from;
    if (auto s = load_checkpoint(o.init_from, model, nullptr, from, o.config); !s.ok()) return s;
    std::printf("starting from the weights of %s (its step %ld)\n", o.init_from.c_str(), static_cast<long>(from.step));
  }
  int64_t params = 0;
  for (const auto& t : model.parameters()) params += t.numel();
  std::printf("model %s: %ld parameters; %d threads\n", o.config.c_str(), static_cast<long>(params), o.threads);

  const SampleOrder order(static_cast<int>(real->scenarios.size()), static_cast<int>(synthetic->scenarios.size()),
                          o.real_fraction, o.seed);
  // CAT-K rolls each sample out with the engine running the current weights: its batches are built between steps
  // (the samples of one batch on `threads` threads), so a resumed run continues exactly. Teacher-forced batches are
  // built on another thread while the previous one trains.
  auto policy_now = [&]() {
    torch::NoGradGuard no_grad;
    return Model::create(model.to_weights());
  };
  if (o.catk_top_k > 0)
    std::printf("CAT-K closed-loop fine-tuning: top %d, targets re-tokenised toward the log\n", o.catk_top_k);
  using Built = std::pair<std::vector<TeacherForcedExample>, DataCursor>;
  auto build = [&](DataCursor cursor, std::shared_ptr<const Model> policy) -> Built {
    const int workers = policy ? o.threads : 1;
    std::vector<TeacherForcedExample> out;
    int failures = 0;
    while (static_cast<int>(out.size()) < o.batch && failures < 100) {
      // Draw what is missing, build it, keep what succeeded in draw order: the same samples as one at a time.
      std::vector<std::future<absl::StatusOr<TeacherForcedExample>>> made;
      for (int i = static_cast<int>(out.size()); i < o.batch; ++i) {
        const int64_t sample = cursor.samples;
        const SampleRef ref = order.next(cursor);
        const Scenario& s = ref.source == 0 ? real->scenarios[ref.scenario] : synthetic->scenarios[ref.scenario];
        const TeacherForcingOptions eo = example_options(o, ref.phase, order.sample_seed(sample));
        made.push_back(std::async(workers > 1 ? std::launch::async : std::launch::deferred, [&, eo, policy, sp = &s] {
          return policy ? closed_loop_example(*sp, *policy, eo, o.catk_top_k) : teacher_forced_example(*sp, *config, eo);
        }));
        const size_t n = made.size(), w = static_cast<size_t>(workers);
        if (n % w == 0)  // at most `workers` at once
          for (size_t j = n - w; j < n; ++j) made[j].wait();
      }
      for (auto& f : made) {
        auto ex = f.get();
        if (ex.ok() && ex->agents > 0) out.push_back(std::move(*ex));
        else ++failures;
      }
    }
    return {std::move(out), cursor};
  };

  // Validation examples: phase 0 of the first val scenarios, agent slots in session order.
  std::vector<TeacherForcedExample> val_examples;
  for (int i = 0; i < static_cast<int>(val->scenarios.size()) && i < o.val_scenarios; ++i) {
    auto ex = teacher_forced_example(val->scenarios[i], *config, example_options(o, 0, 0));
    if (ex.ok()) val_examples.push_back(std::move(*ex));
  }
  auto validate = [&]() {
    torch::NoGradGuard no_grad;
    StatSum s;
    for (const auto& ex : val_examples) {
      const Batch b = make_batch({&ex});
      s.add(compute_loss(model.heads(b, model.forward(b)), b, Stage::all_heads));
    }
    return s;
  };

  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  std::future<Built> pending;
  if (o.catk_top_k == 0) pending = std::async(std::launch::async, build, st.cursor, nullptr);
  const auto session_start = Clock::now();
  auto last_checkpoint = Clock::now();
  double window_tokens = 0, window_seconds = 0, window_loss = 0;
  int window_steps = 0;  // steps in the logged window (fewer than log_every right after a resume)
  StatSum window;
  int64_t steps_here = 0;
  auto checkpoint = [&]() -> absl::Status {
    if (auto s = save_checkpoint(ckpt, model, opt, st, o.config); !s.ok()) return s;
    last_checkpoint = Clock::now();
    return save_weights((dir / "latest.safetensors").string(), model.to_weights());
  };
  while (st.step < o.steps && !g_stop) {
    const auto t0 = Clock::now();  // a step's time includes building its batch (CAT-K) or waiting for it
    Built built;
    if (o.catk_top_k > 0) {
      auto policy = policy_now();
      if (!policy.ok()) return absl::InternalError(absl::StrCat("CAT-K: the engine refused the weights: ", policy.status().message()));
      built = build(st.cursor, *std::move(policy));
    } else {
      built = pending.get();
    }
    auto& [examples, next_cursor] = built;
    if (examples.empty()) return absl::InternalError("could not build any training example from 100 samples in a row");
    st.cursor = next_cursor;
    if (o.catk_top_k == 0) pending = std::async(std::launch::async, build, st.cursor, nullptr);
    std::vector<const TeacherForcedExample*> ptrs;
    for (const auto& e : examples) ptrs.push_back(&e);
    const Batch b = make_batch(ptrs);
    const Stage stage = st.step < o.stage1_steps ? Stage::motion_and_lights : Stage::all_heads;
    const double lr = learning_rate(o, st.step);
    for (auto& group : opt.param_groups()) static_cast<torch::optim::AdamWOptions&>(group.options()).lr(lr);
    opt.zero_grad();
    const Loss loss = compute_loss(model.heads(b, model.forward(b)), b, stage, o.scene_end_weight,
                                   o.placement_weight);
    loss.total.backward();
    torch::nn::utils::clip_grad_norm_(model.parameters(), o.clip);
    opt.step();
    const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    ++st.step;
    ++steps_here;
    st.elapsed += seconds;
    window_tokens += b.tokens();
    window_seconds += seconds;
    window_loss += loss.total.item<double>();
    ++window_steps;
    window.add(loss);
    if (st.step % o.log_every == 0 || st.step == o.steps) {
      const double tps = window_tokens / std::max(1e-9, window_seconds);
      const double per_step = window_seconds / window_steps;
      std::string line = absl::StrFormat("step %d/%d stage %d lr %.2e loss %.3f", st.step, o.steps, static_cast<int>(stage),
                                         lr, window_loss / window_steps);
      for (const char* n : kLogged) absl::StrAppendFormat(&line, " %s %.3f", n, window.mean(n).loss);
      absl::StrAppendFormat(&line, " | %.0f tokens/s, %.2f s/step, ETA %.1f h", tps, per_step,
                            per_step * (o.steps - st.step) / 3600);
      std::printf("%s\n", line.c_str());
      std::fflush(stdout);
      append_line(dir / "train_log.csv", csv_header(),
                  csv_row(st.step, st.elapsed, lr, static_cast<int>(stage), tps, window_loss / window_steps, window));
      window_tokens = window_seconds = window_loss = 0;
      window_steps = 0;
      window = {};
    }
    if (o.val_every > 0 && (st.step % o.val_every == 0 || st.step == o.steps) && !val_examples.empty()) {
      const StatSum v = validate();
      double total = 0;
      for (const char* n : kHeads) total += v.mean(n).loss;
      append_line(dir / "val_log.csv", csv_header(), csv_row(st.step, st.elapsed, lr, static_cast<int>(stage), 0, total, v));
      std::printf("val step %d: motion %.3f (acc %.3f) light %.3f type %.3f end %.3f (first step %.3f) segment %.3f "
                  "state %.3f\n",
                  static_cast<int>(st.step), v.mean("motion").loss, v.mean("motion").accuracy, v.mean("light").loss,
                  v.mean("type").loss, v.mean("end").loss, v.mean("end0").loss, v.mean("segment").loss,
                  v.mean("state").loss);
    }
    const bool time_due = std::chrono::duration<double>(Clock::now() - last_checkpoint).count() > 300;
    if (st.step % o.checkpoint_every == 0 || time_due)
      if (auto s = checkpoint(); !s.ok()) return s;
    if (o.eval_every > 0 && st.step % o.eval_every == 0 && !o.eval_tool.empty()) {
      std::string files;
      for (int i = 0; i < static_cast<int>(val->files.size()) && i < o.eval_scenarios; ++i) files += " " + val->files[i];
      const std::string json = (dir / absl::StrCat("eval_", st.step, ".json")).string();
      const std::string cmd = absl::StrCat(o.eval_tool, " eval --data", files, " --model ", (dir / "latest.safetensors").string(),
                                           " --mode motion --rollouts 4 --threads 1 --json ", json, " > /dev/null 2>&1");
      if (std::system(cmd.c_str()) != 0) std::printf("eval at step %ld failed: %s\n", static_cast<long>(st.step), cmd.c_str());
      else std::printf("eval at step %ld: %s\n", static_cast<long>(st.step), json.c_str());
    }
    if (o.stop_after > 0 && steps_here >= o.stop_after) break;
  }
  if (pending.valid()) pending.wait();
  if (auto s = checkpoint(); !s.ok()) return s;
  std::printf("stopped at step %ld after %.0f s in this process; checkpoint %s\n", static_cast<long>(st.step),
              std::chrono::duration<double>(Clock::now() - session_start).count(), ckpt.c_str());
  return absl::OkStatus();
}

const char* openblas_coretype() {
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx512f")) return "SkylakeX";
  if (__builtin_cpu_supports("avx2")) return "Haswell";
  return "Prescott";
}

absl::Status export_checkpoint(const std::string& checkpoint, const std::string& out) {
  for (const char* name : {"small", "large"}) {
    auto config = model_config_by_name(name);
    TorchModel model(init_weights(*config, 1));
    RunState st;
    const absl::Status s = load_checkpoint(checkpoint, model, nullptr, st, name);
    if (s.ok()) {
      if (auto w = save_weights(out, model.to_weights()); !w.ok()) return w;
      std::printf("exported %s (config %s, step %ld) to %s\n", checkpoint.c_str(), name, static_cast<long>(st.step), out.c_str());
      return absl::OkStatus();
    }
    if (s.message().find("is not of config") == std::string_view::npos) return s;
  }
  return absl::InvalidArgumentError(absl::StrCat("checkpoint ", checkpoint, " holds neither the small nor the large config"));
}

}  // namespace ss::train
