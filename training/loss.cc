#include "training/loss.h"

namespace ss::train {

bool stage_trains(Stage s, const std::string& head) {
  return s == Stage::all_heads || head == "motion" || head == "light";
}

Loss compute_loss(const HeadLogits& logits, const Batch& b, Stage stage, double scene_end_weight,
                  double placement_weight) {
  Loss out;
  out.total = torch::zeros({});
  auto head = [&](const std::string& name, const torch::Tensor& l, const torch::Tensor& target, double weight) {
    HeadStat st;
    st.count = target.numel();
    if (st.count == 0) {
      out.heads[name] = st;
      return;
    }
    const torch::Tensor flat = l.reshape({-1, l.size(-1)});
    const torch::Tensor t = target.reshape({-1});
    const torch::Tensor ce = torch::nn::functional::cross_entropy(flat, t);
    st.loss = ce.item<double>();
    st.accuracy = (flat.detach().argmax(-1) == t).to(torch::kFloat64).mean().item<double>();
    out.heads[name] = st;
    if (stage_trains(stage, name)) out.total = out.total + weight * ce;
  };
  head("light", logits.light, b.light_target, 1.0);
  head("motion", logits.motion, b.motion_target, 1.0);
  head("type", logits.type, b.type_target, placement_weight);
  // The end head: its targets at a sequence's first step say how full a scene is; the rest mostly say that no new
  // agent enters (their count is known from the step before), so they can be weighted up.
  {
    HeadStat st, first;
    st.count = b.end_target.numel();
    if (st.count > 0) {
      const torch::Tensor ce = torch::nn::functional::cross_entropy(
          logits.end, b.end_target, torch::nn::functional::CrossEntropyFuncOptions().reduction(torch::kNone));
      const torch::Tensor right = logits.end.detach().argmax(-1) == b.end_target;
      const torch::Tensor w = torch::where(b.end_first, torch::full({}, scene_end_weight), torch::ones({}));
      const torch::Tensor loss = (ce * w).sum() / w.sum();
      st.loss = ce.detach().mean().item<double>();
      st.accuracy = right.to(torch::kFloat64).mean().item<double>();
      first.count = b.end_first.sum().item<int64_t>();
      if (first.count > 0) {
        first.loss = ce.detach().index({b.end_first}).mean().item<double>();
        first.accuracy = right.index({b.end_first}).to(torch::kFloat64).mean().item<double>();
      }
      if (stage_trains(stage, "end")) out.total = out.total + loss;
    }
    out.heads["end"] = st;
    out.heads["end0"] = first;
  }
  head("state", logits.state, b.state_target, placement_weight);
  // Pointer logits differ in width per example (each map's size): cross-entropy per example, averaged over targets.
  HeadStat seg;
  torch::Tensor sum = torch::zeros({});
  int64_t correct = 0;
  for (size_t e = 0; e < logits.segment.size(); ++e) {
    const torch::Tensor& t = b.segment_target[e];
    if (t.numel() == 0) continue;
    sum = sum + torch::nn::functional::cross_entropy(
                    logits.segment[e], t, torch::nn::functional::CrossEntropyFuncOptions().reduction(torch::kSum));
    correct += (logits.segment[e].detach().argmax(-1) == t).sum().item<int64_t>();
    seg.count += t.numel();
  }
  if (seg.count > 0) {
    const torch::Tensor ce = sum / static_cast<double>(seg.count);
    seg.loss = ce.item<double>();
    seg.accuracy = static_cast<double>(correct) / seg.count;
    if (stage_trains(stage, "segment")) out.total = out.total + placement_weight * ce;
  }
  out.heads["segment"] = seg;
  return out;
}

}  // namespace ss::train
