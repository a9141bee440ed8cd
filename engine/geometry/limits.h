// The one range rule for coordinates and headings that come from outside (scenarios, poses, injected and forced
// states): finite, positions within kMaxCoordinate of the origin, headings within kMaxHeading.
#pragma once

namespace ss {

inline constexpr double kMaxCoordinate = 1e7;  // metres: beyond any real map
inline constexpr double kMaxHeading = 1e3;     // radians: any multiple of 2 pi a client may send, not 1e308

}  // namespace ss
