// Fuzzes the WOMD reading path: the input is a TFRecord file's bytes. Every record that decodes must survive a
// write and a re-read unchanged; anything else (a crash, a sanitizer report, a lossy round trip) is a finding.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "engine/scenario/tfrecord.h"
#include "engine/scenario/womd_proto.h"

namespace {

[[noreturn]] void fail(const char* what, const std::string& detail) {
  std::fprintf(stderr, "womd_tfrecord_fuzz: %s\n%s\n", what, detail.c_str());
  std::abort();
}

// Splits TFRecord framing without checking CRCs or lengths (a length running past the end takes what is there).
std::vector<std::string> loose_records(const uint8_t* data, size_t size) {
  std::vector<std::string> out;
  size_t off = 0;
  while (size - off >= 12) {
    uint64_t len = 0;
    for (int i = 7; i >= 0; --i) len = (len << 8) | data[off + i];
    const size_t left = size - off - 12;
    if (len > left) len = left;
    out.emplace_back(reinterpret_cast<const char*>(data + off + 12), len);
    off += 12 + len + (left - len >= 4 ? 4 : left - len);
  }
  return out;
}

}  // namespace

extern "C" size_t LLVMFuzzerMutate(uint8_t* data, size_t size, size_t max_size);

// Random mutations almost never keep both CRCs right, so most inputs would stop at the framing. Mostly mutate one
// record's payload and re-frame with correct CRCs, so the proto reader is what gets fuzzed; sometimes mutate the raw
// bytes, so the framing errors stay covered.
extern "C" size_t LLVMFuzzerCustomMutator(uint8_t* data, size_t size, size_t max_size, unsigned int seed) {
  std::minstd_rand rng(seed);
  if (rng() % 8 == 0) return LLVMFuzzerMutate(data, size, max_size);
  std::vector<std::string> records = loose_records(data, size);
  if (records.empty()) records.emplace_back();
  if (records.size() < 4 && rng() % 16 == 0) records.push_back(records[rng() % records.size()]);
  std::string& target = records[rng() % records.size()];
  size_t others = 0;
  for (const std::string& r : records) others += 16 + r.size();
  others -= target.size();
  if (others >= max_size) return LLVMFuzzerMutate(data, size, max_size);
  const size_t room = std::max(max_size - others, target.size());
  std::string buf = target;
  buf.resize(room);
  buf.resize(LLVMFuzzerMutate(reinterpret_cast<uint8_t*>(buf.data()), target.size(), room));
  target = std::move(buf);
  std::string framed;
  for (const std::string& r : records) framed += ss::tfrecord_frame(r);
  if (framed.size() > max_size) return LLVMFuzzerMutate(data, size, max_size);
  std::memcpy(data, framed.data(), framed.size());
  return framed.size();
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  auto records = ss::parse_tfrecords(bytes, "fuzz");
  if (!records.ok()) return 0;

  // Framing round trip: re-framing the records gives back the input exactly.
  std::string framed;
  for (const std::string& r : *records) framed += ss::tfrecord_frame(r);
  if (framed != bytes) fail("re-framed records differ from the input", "");

  for (size_t i = 0; i < records->size(); ++i) {
    auto s = ss::scenario_from_womd_bytes((*records)[i], "fuzz record " + std::to_string(i));
    if (!s.ok()) continue;
    // Whatever was read can be written without loss, and reads back as it was.
    if (auto st = ss::check_womd_representable(*s, "fuzz"); !st.ok())
      fail("decoded scenario not writable", st.ToString());
    const std::string once = ss::scenario_to_womd_bytes(*s);
    auto back = ss::scenario_from_womd_bytes(once, "fuzz rewrite");
    if (!back.ok()) fail("a written scenario does not read back", back.status().ToString());
    // The encoding of a representable scenario is injective bit for bit, so equal bytes mean equal scenarios even
    // where operator== cannot tell (NaN in an invalid state's pose is allowed and never equals itself).
    if (ss::scenario_to_womd_bytes(*back) != once) fail("round trip changed the scenario", "");
    bool has_nan = false;
    for (const ss::Track& t : s->tracks)
      for (const ss::ObjectState& o : t.states)
        has_nan |= o.x != o.x || o.y != o.y || o.z != o.z || o.length != o.length || o.width != o.width ||
                   o.height != o.height || o.heading != o.heading || o.vx != o.vx || o.vy != o.vy;
    if (!has_nan && !(*back == *s)) fail("round trip is not operator== equal", "");
  }
  return 0;
}
