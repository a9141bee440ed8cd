// SUMO -> WOMD conventions on hand-written FCD: heading, front bumper -> box centre, velocity, persons.
#include "offline/dataset/sumo_fcd.h"

#include <gtest/gtest.h>

#include <cmath>

namespace ss {
namespace {

TEST(SumoFcd, HeadingFromSumoAngle) {
  // SUMO: degrees clockwise from north. WOMD: radians counter-clockwise from east, in [-pi, pi).
  EXPECT_NEAR(heading_from_sumo_angle(90), 0.0, 1e-12);          // east
  EXPECT_NEAR(heading_from_sumo_angle(0), kPi / 2, 1e-12);       // north
  EXPECT_NEAR(heading_from_sumo_angle(180), -kPi / 2, 1e-12);    // south
  EXPECT_NEAR(std::abs(heading_from_sumo_angle(270)), kPi, 1e-12);  // west
  EXPECT_NEAR(heading_from_sumo_angle(45), kPi / 4, 1e-12);      // north-east
  EXPECT_NEAR(heading_from_sumo_angle(360 + 45), kPi / 4, 1e-12);
  EXPECT_NEAR(heading_from_sumo_angle(-45), 3 * kPi / 4, 1e-12);  // north-west
  for (double a = -720; a <= 720; a += 7.5) {
    const double h = heading_from_sumo_angle(a);
    EXPECT_GE(h, -kPi);
    EXPECT_LT(h, kPi);
  }
}

TEST(SumoFcd, CentreIsHalfALengthBehindTheFrontBumper) {
  const Vec2 c = centre_from_front({10, 20}, 0.0, 4.0);  // heading east: the centre is 2 m west of the front
  EXPECT_NEAR(c.x, 8.0, 1e-12);
  EXPECT_NEAR(c.y, 20.0, 1e-12);
  const Vec2 n = centre_from_front({10, 20}, kPi / 2, 5.0);  // north: 2.5 m south
  EXPECT_NEAR(n.x, 10.0, 1e-12);
  EXPECT_NEAR(n.y, 17.5, 1e-12);
}

const char* kFcd = R"(<?xml version="1.0" encoding="UTF-8"?>
<fcd-export>
    <timestep time="300.00">
        <vehicle id="v1" x="100.00" y="50.00" angle="90.00" type="car0" speed="10.00"/>
        <person id="p1" x="5.00" y="6.00" angle="0.00" speed="1.20"/>
    </timestep>
    <timestep time="300.10">
        <vehicle id="v1" x="101.00" y="50.00" angle="90.00" type="car0" speed="10.00"/>
        <vehicle id="b1" x="0.00" y="0.00" angle="180.00" type="bike0" speed="5.00"/>
        <person id="p1" x="5.00" y="6.12" angle="0.00" speed="1.20"/>
    </timestep>
    <timestep time="300.20">
        <vehicle id="b1" x="0.00" y="-0.50" angle="180.00" type="bike0" speed="5.00"/>
    </timestep>
    <timestep time="300.30">
        <vehicle id="v1" x="103.00" y="50.00" angle="90.00" type="car0" speed="10.00"/>
    </timestep>
</fcd-export>
)";

AgentKinds kinds() {
  return {{"car0", {ObjectType::vehicle, 4.0f, 2.0f, 1.5f}},
          {"bike0", {ObjectType::cyclist, 1.8f, 0.8f, 1.7f}},
          {"ped0", {ObjectType::pedestrian, 0.8f, 0.6f, 1.7f}}};
}

TEST(SumoFcd, TracksInWomdConventions) {
  auto rec = parse_fcd(kFcd, "fcd.xml", kinds(), {{"p1", "ped0"}}, 0.1);
  ASSERT_TRUE(rec.ok()) << rec.status();
  EXPECT_DOUBLE_EQ(rec->begin, 300.0);
  EXPECT_EQ(rec->frames, 4);
  ASSERT_EQ(rec->tracks.size(), 3u);  // ordered by id: b1, p1, v1
  const FcdTrack& bike = rec->tracks[0];
  const FcdTrack& person = rec->tracks[1];
  const FcdTrack& car = rec->tracks[2];
  EXPECT_EQ(car.id, "v1");
  EXPECT_EQ(car.kind.type, ObjectType::vehicle);
  ASSERT_NE(car.at(0), nullptr);
  EXPECT_NEAR(car.at(0)->x, 98.0, 1e-9);  // front bumper at 100, heading east, length 4
  EXPECT_NEAR(car.at(0)->y, 50.0, 1e-9);
  EXPECT_NEAR(car.at(0)->heading, 0.0, 1e-6);
  EXPECT_FLOAT_EQ(car.at(0)->speed, 10.0f);
  EXPECT_EQ(car.at(2), nullptr);  // absent for a frame (teleporting): a gap, not a made-up state
  ASSERT_NE(car.at(3), nullptr);
  EXPECT_NEAR(car.at(3)->x, 101.0, 1e-9);
  // Bicycles are vehicles in SUMO: the same front-bumper convention. Heading south, length 1.8.
  EXPECT_EQ(bike.kind.type, ObjectType::cyclist);
  EXPECT_EQ(bike.first_frame, 1);
  EXPECT_NEAR(bike.at(1)->y, 0.9, 1e-6);  // 0.5 * 1.8f
  EXPECT_NEAR(bike.at(1)->heading, -kPi / 2, 1e-6);
  // Persons: the position is the centre. The type comes from the table (SUMO writes none for persons).
  EXPECT_EQ(person.kind.type, ObjectType::pedestrian);
  EXPECT_NEAR(person.at(1)->y, 6.12, 1e-9);
  EXPECT_NEAR(person.at(1)->heading, kPi / 2, 1e-6);
  EXPECT_EQ(rec->frame_of(300.2), 2);
}

TEST(SumoFcd, UnknownTypesAndBadTimestepsAreErrors) {
  auto no_person_type = parse_fcd(kFcd, "fcd.xml", kinds(), {}, 0.1);
  ASSERT_FALSE(no_person_type.ok());
  EXPECT_NE(no_person_type.status().message().find("person p1"), std::string_view::npos)
      << no_person_type.status().message();
  EXPECT_NE(no_person_type.status().message().find("fcd.xml:5"), std::string_view::npos);

  const std::string skipped = R"(<fcd-export><timestep time="1.0"></timestep>
<timestep time="1.2"></timestep></fcd-export>)";
  auto gap = parse_fcd(skipped, "gap.xml", kinds(), {}, 0.1);
  ASSERT_FALSE(gap.ok());
  EXPECT_NE(gap.status().message().find("gap.xml:2"), std::string_view::npos) << gap.status().message();
}

}  // namespace
}  // namespace ss
