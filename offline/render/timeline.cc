#include "offline/render/timeline.h"

#include "offline/render/svg_text.h"

namespace ss {

Timeline Timeline::still(int frame) {
  Timeline t;
  t.frames_ = {frame};
  return t;
}

Timeline Timeline::animation(int num_frames, double frame_s) {
  Timeline t;
  for (int i = 0; i < num_frames; ++i) t.frames_.push_back(i);
  t.frame_s_ = frame_s;
  t.animated_ = true;
  return t;
}

std::string Timeline::animate(std::string_view attribute, const std::vector<std::string>& values) const {
  return keyed("animate", "attributeName=\"" + std::string(attribute) + "\"", values);
}

std::string Timeline::animate_transform(std::string_view type, const std::vector<std::string>& values) const {
  return keyed("animateTransform", "attributeName=\"transform\" type=\"" + std::string(type) + "\"", values);
}

std::string Timeline::keyed(std::string_view element, std::string_view head,
                            const std::vector<std::string>& values) const {
  if (!animated_ || values.empty()) return "";
  std::string key_values, key_times;
  for (size_t i = 0; i < values.size(); ++i) {
    if (i > 0 && values[i] == values[i - 1]) continue;
    if (i > 0) key_values += ';', key_times += ';';
    key_values += values[i];
    key_times += svg_num(static_cast<double>(i) / values.size(), 4);
  }
  if (key_times == "0") return "";  // never changes
  std::string out = "<";
  out += element;
  out += ' ';
  out += head;
  out += " calcMode=\"discrete\" dur=\"" + svg_num(duration_s(), 3) + "s\" repeatCount=\"indefinite\" keyTimes=\"" +
         key_times + "\" values=\"" + key_values + "\"/>";
  return out;
}

}  // namespace ss
