// Which frames a picture shows, and how an animated picture changes an attribute from frame to frame.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace ss {

class Timeline {
 public:
  // One frame, drawn as a still.
  static Timeline still(int frame);
  // Every frame 0..num_frames-1, each shown for `frame_s` seconds, looping.
  static Timeline animation(int num_frames, double frame_s);

  bool animated() const { return animated_; }
  // The scenario frame shown at each drawn index.
  const std::vector<int>& frames() const { return frames_; }
  int size() const { return static_cast<int>(frames_.size()); }
  double duration_s() const { return frames_.size() * frame_s_; }

  // A SMIL element that sets `attribute` to values[i] while drawn frame i shows: discrete (no interpolation between
  // frames, which would slide a disappearing agent across the map) with one key per change, so a parked car costs a
  // single key. values has one entry per drawn frame. Empty for a still or a value that never changes; the caller
  // writes values[0] as the attribute itself, which is also what viewers without SMIL show.
  std::string animate(std::string_view attribute, const std::vector<std::string>& values) const;
  // The same for the `transform` attribute; `type` is "translate" or "rotate" and values are their arguments.
  std::string animate_transform(std::string_view type, const std::vector<std::string>& values) const;

 private:
  std::string keyed(std::string_view element, std::string_view head, const std::vector<std::string>& values) const;

  std::vector<int> frames_;
  double frame_s_ = 0.1;
  bool animated_ = false;
};

}  // namespace ss
