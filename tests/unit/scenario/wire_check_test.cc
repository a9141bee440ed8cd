#include "engine/scenario/wire_check.h"

#include <cstring>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "womd/scenario.pb.h"

namespace ss {
namespace {

using ::testing::HasSubstr;
namespace wo = waymo::open_dataset;

// Hand-made wire bytes, so each test can put exactly one thing wrong.
std::string varint(uint64_t v) {
  std::string s;
  while (v >= 0x80) {
    s += static_cast<char>((v & 0x7F) | 0x80);
    v >>= 7;
  }
  s += static_cast<char>(v);
  return s;
}
std::string tag(int field, int wt) { return varint((static_cast<uint64_t>(field) << 3) | wt); }
std::string vfield(int field, uint64_t v) { return tag(field, 0) + varint(v); }
std::string lfield(int field, const std::string& payload) { return tag(field, 2) + varint(payload.size()) + payload; }
std::string dfield(int field, double d) {
  std::string s = tag(field, 1);
  char b[8];
  std::memcpy(b, &d, 8);
  return s + std::string(b, 8);
}
std::string ffield(int field, float f) {
  std::string s = tag(field, 5);
  char b[4];
  std::memcpy(b, &f, 4);
  return s + std::string(b, 4);
}


absl::Status check_scenario(const std::string& bytes) {
  return check_wire(bytes, *wo::Scenario::descriptor(), "x.tfrecord record 2");
}

std::string msg(const absl::Status& s) { return std::string(s.message()); }

std::string good_state() {
  return dfield(2, 1.5) + dfield(3, 2.5) + dfield(4, 0.1) + ffield(5, 4) + ffield(6, 2) + ffield(7, 1.5) +
         ffield(8, 0.3) + ffield(9, 1) + ffield(10, 0) + vfield(11, 1);
}

TEST(WireCheck, GeneratedBytesPass) {
  wo::Scenario s;
  s.set_scenario_id("abc");
  for (int i = 0; i < 3; ++i) s.add_timestamps_seconds(0.1 * i);
  wo::Track* t = s.add_tracks();
  t->set_id(-5);  // a 10-byte varint
  t->set_object_type(wo::Track::TYPE_CYCLIST);
  t->add_states()->set_center_x(3);
  wo::MapFeature* f = s.add_map_features();
  f->set_id(-1);
  f->mutable_lane()->add_entry_lanes(-7);
  f->mutable_lane()->add_entry_lanes(12);
  f->mutable_lane()->add_left_neighbors()->add_boundaries()->set_boundary_type(wo::RoadLine::TYPE_SOLID_DOUBLE_YELLOW);
  s.add_objects_of_interest(-3);
  s.add_compressed_frame_laser_data(std::string("\xFF\xFE\x00", 3));  // bytes: no UTF-8 check
  EXPECT_TRUE(check_scenario(s.SerializeAsString()).ok()) << check_scenario(s.SerializeAsString());
  EXPECT_TRUE(check_scenario("").ok());
}

TEST(WireCheck, WrongWireTypeNamesTheNestedField) {
  // Scenario.tracks[3].states[7].center_x sent as a varint.
  std::string track = vfield(1, 1);
  for (int i = 0; i < 7; ++i) track += lfield(3, good_state());
  track += lfield(3, vfield(2, 42));
  std::string bytes;
  for (int i = 0; i < 3; ++i) bytes += lfield(2, vfield(1, 10 + i));
  bytes += lfield(2, track);
  const absl::Status st = check_scenario(bytes);
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(msg(st), HasSubstr("x.tfrecord record 2: Scenario.tracks[3].states[7].center_x: wire type 0 (varint), "
                                 "expected 1 (64-bit) for double (byte offset "));

  // And the reason this check exists: libprotobuf takes the same bytes without complaint and loses the value.
  wo::Scenario parsed;
  ASSERT_TRUE(parsed.ParseFromString(bytes));
  EXPECT_FALSE(parsed.tracks(3).states(7).has_center_x());
}

TEST(WireCheck, ByteOffsetPointsAtTheTag) {
  const std::string bytes = lfield(5, "id") + dfield(10, 1.0);  // current_time_index is an int32
  const absl::Status st = check_scenario(bytes);
  EXPECT_THAT(msg(st), HasSubstr("Scenario.current_time_index: wire type 1 (64-bit), expected 0 (varint) for int32"));
  EXPECT_THAT(msg(st), HasSubstr("(byte offset 4)"));
}

TEST(WireCheck, MessageFieldWithScalarWireType) {
  const absl::Status st = check_scenario(vfield(2, 3));
  EXPECT_THAT(msg(st), HasSubstr("Scenario.tracks[0]: wire type 0 (varint), expected 2 (length-delimited) for "
                                 "repeated message Track"));
}

TEST(WireCheck, TruncatedVarint) {
  EXPECT_THAT(msg(check_scenario(tag(10, 0) + "\x80\x80")),
              HasSubstr("Scenario.current_time_index: truncated varint"));
  EXPECT_THAT(msg(check_scenario(tag(10, 0))), HasSubstr("Scenario.current_time_index: truncated varint"));
  EXPECT_THAT(msg(check_scenario("\x80")), HasSubstr("Scenario: truncated tag varint"));
  // Eleven bytes: longer than any varint may be.
  EXPECT_THAT(msg(check_scenario(tag(6, 0) + std::string(10, '\x80') + "\x01")),
              HasSubstr("Scenario.sdc_track_index: varint is longer than 10 bytes"));
}

TEST(WireCheck, TruncatedFixed) {
  EXPECT_THAT(msg(check_scenario(tag(1, 1) + "abc")), HasSubstr("Scenario.timestamps_seconds[0]: truncated double"));
}

TEST(WireCheck, LengthPastEnd) {
  const absl::Status st = check_scenario(tag(2, 2) + varint(100) + "abc");
  EXPECT_THAT(msg(st), HasSubstr("Scenario.tracks[0]: length 100 runs past the end of the enclosing message (3 bytes"));
  // A sub-message's length is bounded by its parent, not by the whole buffer.
  const std::string inner = tag(3, 2) + varint(20) + "xy";
  EXPECT_THAT(msg(check_scenario(lfield(2, inner) + std::string(30, '\0'))),
              HasSubstr("Scenario.tracks[0].states[0]: length 20 runs past the end"));
}

TEST(WireCheck, BadUtf8InScenarioId) {
  const std::string bytes = lfield(5, "ab\xC3\x28");
  EXPECT_THAT(msg(check_scenario(bytes)), HasSubstr("Scenario.scenario_id: string is not valid UTF-8"));
  wo::Scenario parsed;
  EXPECT_TRUE(parsed.ParseFromString(bytes));  // proto2: libprotobuf does not look
  EXPECT_TRUE(check_scenario(lfield(5, "caf\xC3\xA9 \xE2\x82\xAC \xF0\x9F\x98\x80")).ok());
}

TEST(WireCheck, PackedAndUnpackedRepeatedScalarsAccepted) {
  // timestamps_seconds unpacked (as in real files) and packed; objects_of_interest both ways; entry_lanes both ways.
  std::string packed_doubles;
  for (double d : {0.0, 0.1, 0.2}) {
    char b[8];
    std::memcpy(b, &d, 8);
    packed_doubles.append(b, 8);
  }
  const std::string lane_unpacked = vfield(9, 5) + vfield(9, static_cast<uint64_t>(-6));
  const std::string lane_packed = lfield(10, varint(7) + varint(static_cast<uint64_t>(-8)));
  const std::string bytes = dfield(1, -0.1) + lfield(1, packed_doubles) + vfield(4, 625) +
                            lfield(4, varint(2694) + varint(3)) +
                            lfield(8, vfield(1, 9) + lfield(3, lane_unpacked + lane_packed));
  ASSERT_TRUE(check_scenario(bytes).ok()) << check_scenario(bytes);
  wo::Scenario parsed;
  ASSERT_TRUE(parsed.ParseFromString(bytes));
  EXPECT_EQ(parsed.timestamps_seconds_size(), 4);
  EXPECT_EQ(parsed.objects_of_interest_size(), 3);
  EXPECT_EQ(parsed.map_features(0).lane().entry_lanes_size(), 2);
  EXPECT_EQ(parsed.map_features(0).lane().exit_lanes(1), -8);
  // Packed element indices continue the count: the third timestamp is [2].
  const std::string bad_packed = dfield(1, 0) + lfield(1, packed_doubles.substr(0, 12));
  EXPECT_THAT(msg(check_scenario(bad_packed)),
              HasSubstr("Scenario.timestamps_seconds[1]: packed length 12 is not a multiple of 8"));
  // A packed varint element with a bad value is named by its index.
  EXPECT_THAT(msg(check_scenario(lfield(4, varint(1) + varint(uint64_t{1} << 40)))),
              HasSubstr("Scenario.objects_of_interest[1]: value 1099511627776 does not fit int32"));
  // Packed encoding is for repeated scalars only.
  EXPECT_THAT(msg(check_scenario(lfield(10, varint(1)))),
              HasSubstr("Scenario.current_time_index: wire type 2 (length-delimited), expected 0 (varint) for int32"));
}

TEST(WireCheck, UnknownFieldsSkipped) {
  const std::string bytes = lfield(3, "") + lfield(5, "id") + vfield(99, 12345) + tag(100, 5) + "abcd" +
                            tag(101, 1) + "abcdefgh" + tag(102, 3) + vfield(1, 1) + lfield(2, "x") + tag(102, 4) +
                            lfield(9, "reserved") + lfield(2, vfield(1, 3) + lfield(77, "zz"));
  EXPECT_TRUE(check_scenario(bytes).ok()) << check_scenario(bytes);
  // Unknown fields must still be well-formed.
  EXPECT_THAT(msg(check_scenario(tag(3, 2) + varint(5) + "ab")), HasSubstr("Scenario.<field 3>: length 5 runs past"));
  EXPECT_THAT(msg(check_scenario(tag(102, 3) + vfield(1, 1))), HasSubstr("has no end-group tag"));
  EXPECT_THAT(msg(check_scenario(tag(40, 7))), HasSubstr("invalid wire type 7"));
  EXPECT_THAT(msg(check_scenario(tag(0, 0) + varint(1))), HasSubstr("field number 0 is invalid"));
}

TEST(WireCheck, UnknownEnumValueIsAnError) {
  const std::string bytes = lfield(2, vfield(1, 4) + vfield(2, 9));
  EXPECT_THAT(msg(check_scenario(bytes)),
              HasSubstr("Scenario.tracks[0].object_type: value 9 is not a known Track.ObjectType value"));
  wo::Scenario parsed;  // what libprotobuf would do: keep it out of sight
  ASSERT_TRUE(parsed.ParseFromString(bytes));
  EXPECT_FALSE(parsed.tracks(0).has_object_type());
  EXPECT_THAT(msg(check_scenario(lfield(2, vfield(2, static_cast<uint64_t>(-1))))),
              HasSubstr("value -1 is not a known Track.ObjectType value"));
}

TEST(WireCheck, NestingPathInMessage) {
  // map_features[1].lane.left_neighbors[0].boundaries[2].boundary_type = 42.
  const std::string seg_ok = vfield(4, 1);
  const std::string neighbor = vfield(1, 7) + lfield(6, seg_ok) + lfield(6, seg_ok) + lfield(6, vfield(4, 42));
  const std::string bytes =
      lfield(8, vfield(1, 1) + lfield(4, "")) + lfield(8, vfield(1, 2) + lfield(3, lfield(11, neighbor)));
  EXPECT_THAT(msg(check_scenario(bytes)),
              HasSubstr("x.tfrecord record 2: Scenario.map_features[1].lane.left_neighbors[0].boundaries[2]."
                        "boundary_type: value 42 is not a known RoadLine.RoadLineType value"));
}

TEST(WireCheck, OneofSetTwiceIsAnError) {
  const std::string bytes = lfield(8, vfield(1, 1) + lfield(3, "") + lfield(4, ""));
  EXPECT_THAT(msg(check_scenario(bytes)),
              HasSubstr("Scenario.map_features[0].road_line: oneof feature_data already holds lane"));
  // The same member twice merges, as protobuf specifies: no loss.
  EXPECT_TRUE(check_scenario(lfield(8, lfield(3, "") + lfield(3, ""))).ok());
}

TEST(WireCheck, ScalarRanges) {
  EXPECT_THAT(msg(check_scenario(lfield(2, lfield(3, vfield(11, 2))))),
              HasSubstr("Scenario.tracks[0].states[0].valid: value 2 is not a bool"));
  EXPECT_THAT(msg(check_scenario(vfield(6, uint64_t{1} << 31))),
              HasSubstr("Scenario.sdc_track_index: value 2147483648 does not fit int32"));
  EXPECT_TRUE(check_scenario(vfield(6, static_cast<uint64_t>(int64_t{-1}))).ok());
  EXPECT_THAT(msg(check_scenario(vfield(6, ~uint64_t{0} >> 1))), HasSubstr("does not fit int32"));
}

TEST(WireCheck, DepthLimit) {
  std::string deep;
  for (int i = 0; i < 200; ++i) deep += tag(50, 3);
  for (int i = 0; i < 200; ++i) deep += tag(50, 4);
  EXPECT_THAT(msg(check_scenario(deep)), HasSubstr("nesting deeper than 64 levels"));
  std::string ok;
  for (int i = 0; i < 10; ++i) ok += tag(50, 3);
  for (int i = 0; i < 10; ++i) ok += tag(50, 4);
  EXPECT_TRUE(check_scenario(ok).ok()) << check_scenario(ok);
  EXPECT_THAT(msg(check_scenario(tag(50, 4))), HasSubstr("unexpected end-group tag for field 50"));
}

TEST(Utf8, Validity) {
  EXPECT_TRUE(is_valid_utf8(""));
  EXPECT_TRUE(is_valid_utf8("plain ascii"));
  EXPECT_TRUE(is_valid_utf8("\xC3\xA9\xE2\x82\xAC\xF0\x9F\x98\x80\xF4\x8F\xBF\xBF"));
  EXPECT_FALSE(is_valid_utf8("\xC0\x80"));          // overlong NUL
  EXPECT_FALSE(is_valid_utf8("\xE0\x80\xAF"));      // overlong '/'
  EXPECT_FALSE(is_valid_utf8("\xED\xA0\x80"));      // surrogate
  EXPECT_FALSE(is_valid_utf8("\xF4\x90\x80\x80"));  // above U+10FFFF
  EXPECT_FALSE(is_valid_utf8("\x80"));              // lone continuation
  EXPECT_FALSE(is_valid_utf8("\xE2\x82"));          // cut short
  EXPECT_FALSE(is_valid_utf8("\xFF"));
}

}  // namespace
}  // namespace ss
