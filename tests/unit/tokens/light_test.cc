#include "engine/tokens/light.h"

#include <gtest/gtest.h>

namespace ss {
namespace {

TEST(Light, NineWomdStatesOntoFour) {
  const std::pair<SignalState, LightState> table[] = {
      {SignalState::unknown, LightState::unknown},       {SignalState::arrow_stop, LightState::red},
      {SignalState::arrow_caution, LightState::yellow},  {SignalState::arrow_go, LightState::green},
      {SignalState::stop, LightState::red},              {SignalState::caution, LightState::yellow},
      {SignalState::go, LightState::green},              {SignalState::flashing_stop, LightState::red},
      {SignalState::flashing_caution, LightState::yellow}};
  for (auto [womd, ours] : table) EXPECT_EQ(light_state_from_womd(womd), ours) << static_cast<int>(womd);
  EXPECT_EQ(static_cast<int>(LightState::unknown), 0);  // paper appendix E numbering
  EXPECT_EQ(static_cast<int>(LightState::green), 1);
  EXPECT_EQ(static_cast<int>(LightState::yellow), 2);
  EXPECT_EQ(static_cast<int>(LightState::red), 3);
  EXPECT_STREQ(light_state_name(LightState::yellow), "yellow");
}

}  // namespace
}  // namespace ss
