// What the example C++ clients share: their flags, the connection, the scenarios' names, the ego's controller and
// closing a session.
#pragma once

#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "grpcpp/grpcpp.h"
#include "scenestreamer/v1/simulator.grpc.pb.h"

namespace client {

namespace pb = scenestreamer::v1;

inline const char* const kDefaultTarget = "127.0.0.1:50051";

// Command-line flags: "--name VALUE" for the names in `valued`, a bare "--name" for those in `switches` (names
// without the dashes). A flag given twice keeps its last value.
struct Flags {
  std::map<std::string, std::string> values;
  std::set<std::string> switches;
};

// Parses argv[1..]. False on an unknown flag, a stray argument or a valued flag without its value: the caller then
// prints its usage.
bool parse_flags(int argc, char** argv, const std::vector<std::string>& valued, const std::vector<std::string>& switches,
                 Flags* flags);

// A flag's value, or `fallback` when it was not given. Numbers are read with std::atoi, so "abc" is 0.
std::string flag_string(const Flags& flags, const std::string& name, const std::string& fallback);
int flag_int(const Flags& flags, const std::string& name, int fallback);

// The metadata a session-affine router hashes (deploy/router/): with it on every call of a session, CreateSession
// included, all of them reach the replica that holds the session. The client proposes the id, so the router can place
// the session before it exists.
inline const char* const kSessionIdHeader = "x-session-id";

// A fresh session id to propose: 128 random bits in hex.
std::string new_session_id();

// Adds the x-session-id metadata to a call when `session_id` is not empty (clients that route by session pass it).
void route_by(grpc::ClientContext* ctx, const std::string& session_id);

// A stub over an insecure channel: the examples talk to a server on the same host or network.
std::unique_ptr<pb::Simulator::Stub> connect(const std::string& target);

// The names of the server's scenarios, in its order, into `*names`; empty when it has none.
grpc::Status scenario_names(pb::Simulator::Stub& stub, std::vector<std::string>* names);

// The examples' ego controller: every controlled agent keeps its heading and speed for the next 0.5 s.
pb::StepSceneRequest keep_heading_and_speed(const std::string& session_id, const pb::Tick& tick);

// Closes the session (the server would otherwise keep it until it is evicted). `route` as in route_by.
grpc::Status close_session(pb::Simulator::Stub& stub, const std::string& session_id, const std::string& route = "");

}  // namespace client
