#include "viewer/gateway.h"

#include <dlfcn.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>
#include <thread>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_replace.h"
#include "civetweb.h"
#include "engine/io/json_strict.h"
#include "engine/scenario/read.h"
#include "spdlog/spdlog.h"
#include "viewer/convert.h"

namespace viewer {
namespace {

using nlohmann::json;

constexpr auto kCallTimeout = std::chrono::seconds(10);

const char* code_name(grpc::StatusCode c) {
  switch (c) {
    case grpc::OK: return "OK";
    case grpc::CANCELLED: return "CANCELLED";
    case grpc::INVALID_ARGUMENT: return "INVALID_ARGUMENT";
    case grpc::DEADLINE_EXCEEDED: return "DEADLINE_EXCEEDED";
    case grpc::NOT_FOUND: return "NOT_FOUND";
    case grpc::ALREADY_EXISTS: return "ALREADY_EXISTS";
    case grpc::PERMISSION_DENIED: return "PERMISSION_DENIED";
    case grpc::RESOURCE_EXHAUSTED: return "RESOURCE_EXHAUSTED";
    case grpc::FAILED_PRECONDITION: return "FAILED_PRECONDITION";
    case grpc::ABORTED: return "ABORTED";
    case grpc::UNAVAILABLE: return "UNAVAILABLE";
    case grpc::UNAUTHENTICATED: return "UNAUTHENTICATED";
    case grpc::INTERNAL: return "INTERNAL";
    default: return "UNKNOWN";
  }
}

int http_status(grpc::StatusCode c) {
  switch (c) {
    case grpc::INVALID_ARGUMENT: return 400;
    case grpc::UNAUTHENTICATED: return 401;
    case grpc::PERMISSION_DENIED: return 403;
    case grpc::NOT_FOUND: return 404;
    case grpc::RESOURCE_EXHAUSTED: return 429;
    case grpc::DEADLINE_EXCEEDED: return 504;
    default: return 502;
  }
}

// "ListSessions at the server 127.0.0.1:50051: UNAUTHENTICATED: ..." (what the page shows).
std::string rpc_error(const Gateway& gw, const char* rpc, const grpc::Status& st) {
  std::string msg = absl::StrCat(rpc, " at the server ", gw.target(), ": ", code_name(st.error_code()), ": ",
                                 st.error_message());
  if (st.error_code() == grpc::UNAVAILABLE) msg += " (is the server running, and is --target right?)";
  return msg;
}

void prepare(grpc::ClientContext* ctx, const std::string& token) {
  if (!token.empty()) ctx->AddMetadata("authorization", "Bearer " + token);
  ctx->set_deadline(std::chrono::system_clock::now() + kCallTimeout);
}

const char* reason(int status) {
  switch (status) {
    case 200: return "OK";
    case 400: return "Bad Request";
    case 401: return "Unauthorized";
    case 403: return "Forbidden";
    case 404: return "Not Found";
    case 405: return "Method Not Allowed";
    case 411: return "Length Required";
    case 413: return "Payload Too Large";
    case 429: return "Too Many Requests";
    case 504: return "Gateway Timeout";
    default: return "Bad Gateway";
  }
}

int send(mg_connection* conn, int status, const std::string& body) {
  mg_printf(conn,
            "HTTP/1.1 %d %s\r\nContent-Type: application/json\r\nContent-Length: %zu\r\nCache-Control: no-store\r\n"
            "Connection: close\r\n\r\n",
            status, reason(status), body.size());
  mg_write(conn, body.data(), body.size());
  return status;
}

int send_error(mg_connection* conn, int status, const std::string& message, const std::string& code = "") {
  spdlog::info("viewer: {} {}: {}", mg_get_request_info(conn)->request_uri, status, message);
  return send(conn, status, json{{"error", message}, {"code", code}}.dump());
}

int send_rpc_error(mg_connection* conn, const Gateway& gw, const char* rpc, const grpc::Status& st) {
  return send_error(conn, http_status(st.error_code()), rpc_error(gw, rpc, st), code_name(st.error_code()));
}

// The bearer token of a request: "" without an Authorization header; false when the header is malformed.
bool request_token(mg_connection* conn, std::string* token, std::string* why) {
  const char* h = mg_get_header(conn, "Authorization");
  token->clear();
  if (!h || !*h) return true;
  const std::string header = h;
  if (!header.starts_with("Bearer ")) {
    *why = "the Authorization header must be `Bearer TOKEN`";
    return false;
  }
  *token = header.substr(7);
  if (!token_ok(*token)) {
    *why = "the token in the Authorization header holds a character other than letters, digits and -._~+/=, or is "
           "longer than 512";
    return false;
  }
  return true;
}

std::string query_var(mg_connection* conn, const char* name) {
  const char* q = mg_get_request_info(conn)->query_string;
  if (!q) return "";
  char buf[1024];
  const int n = mg_get_var(q, std::strlen(q), name, buf, sizeof buf);
  return n < 0 ? "" : std::string(buf, n);
}

bool is_method(mg_connection* conn, const char* m) { return std::strcmp(mg_get_request_info(conn)->request_method, m) == 0; }

int handle_sessions(mg_connection* conn, void* data) {
  Gateway& gw = *static_cast<Gateway*>(data);
  if (!is_method(conn, "GET")) return send_error(conn, 405, "/api/sessions takes GET");
  std::string token, why;
  if (!request_token(conn, &token, &why)) return send_error(conn, 400, why);
  grpc::ClientContext ctx;
  prepare(&ctx, token);
  pb::ListSessionsResponse list;
  const grpc::Status st = gw.stub().ListSessions(&ctx, {}, &list);
  if (!st.ok()) return send_rpc_error(conn, gw, "ListSessions", st);
  json sessions = json::array();
  for (const pb::SessionInfo& s : list.sessions()) sessions.push_back(session_json(s));
  return send(conn, 200, json{{"server", gw.target()}, {"sessions", sessions}}.dump());
}

int handle_map(mg_connection* conn, void* data) {
  Gateway& gw = *static_cast<Gateway*>(data);
  if (!is_method(conn, "GET")) return send_error(conn, 405, "/api/map takes GET");
  std::string token, why;
  if (!request_token(conn, &token, &why)) return send_error(conn, 400, why);
  const std::string id = query_var(conn, "session");
  if (id.empty()) return send_error(conn, 400, "/api/map needs ?session=ID");
  grpc::ClientContext ctx;
  prepare(&ctx, token);
  pb::GetSessionRequest req;
  req.set_session_id(id);
  pb::GetSessionResponse resp;
  const grpc::Status st = gw.stub().GetSession(&ctx, req, &resp);
  if (!st.ok()) return send_rpc_error(conn, gw, "GetSession", st);
  const std::string& name = resp.info().scenario_name();
  const KnownScenario* known = gw.scenario(name);
  if (!known)
    return send_error(conn, 404,
                      name.empty() ? "the session runs on a scenario its client sent: the viewer has no map for it"
                                   : absl::StrCat("scenario '", name, "' is not among the viewer's --scenario_dir "
                                                  "scenarios: start the viewer with the server's --scenario_dir"),
                      "NO_MAP");
  return send(conn, 200, known->map_json);
}

int handle_rollout(mg_connection* conn, void* data) {
  Gateway& gw = *static_cast<Gateway*>(data);
  if (!is_method(conn, "POST")) return send_error(conn, 405, "/api/rollout takes POST with the file as the body");
  std::string token, why;
  if (!request_token(conn, &token, &why)) return send_error(conn, 400, why);
  {  // The server decides who may use the viewer: the same token ListSessions takes.
    grpc::ClientContext ctx;
    prepare(&ctx, token);
    pb::ListSessionsResponse list;
    const grpc::Status st = gw.stub().ListSessions(&ctx, {}, &list);
    if (!st.ok()) return send_rpc_error(conn, gw, "ListSessions", st);
  }
  const char* name_header = mg_get_header(conn, "X-File-Name");
  const std::string name = name_header && *name_header ? name_header : "upload";
  const long long length = mg_get_request_info(conn)->content_length;
  if (length < 0) return send_error(conn, 411, "/api/rollout needs a Content-Length");
  if (length == 0) return send_error(conn, 400, absl::StrCat("file '", name, "' is empty"));
  if (static_cast<unsigned long long>(length) > gw.options().max_upload_bytes)
    return send_error(conn, 413, absl::StrCat("file '", name, "' is ", length, " bytes; the viewer takes at most ",
                                              gw.options().max_upload_bytes, " (--max_upload_mb)"));
  std::string body(static_cast<size_t>(length), '\0');
  size_t got = 0;
  while (got < body.size()) {
    const int n = mg_read(conn, body.data() + got, body.size() - got);
    if (n <= 0) break;
    got += static_cast<size_t>(n);
  }
  if (got != body.size())
    return send_error(conn, 400, absl::StrCat("file '", name, "': the upload ended after ", got, " of ", length, " bytes"));
  // The readers take a path, and decide the format by its name: .json is GPUDrive/Nocturne JSON, else a TFRecord.
  const bool is_json = name.ends_with(".json");
  std::string path = (std::filesystem::temp_directory_path() / "ss-viewer-XXXXXX").string() + (is_json ? ".json" : ".tfrecord");
  const int fd = mkstemps(path.data(), is_json ? 5 : 9);
  if (fd < 0) return send_error(conn, 502, absl::StrCat("cannot make a temporary file for '", name, "': ", std::strerror(errno)));
  const bool written = ::write(fd, body.data(), body.size()) == static_cast<ssize_t>(body.size());
  ::close(fd);
  absl::StatusOr<std::vector<ss::Scenario>> scenarios =
      written ? ss::read_scenarios(path) : absl::InternalError("cannot write the temporary file");
  std::filesystem::remove(path);
  if (!scenarios.ok())
    return send_error(conn, 400, absl::StrReplaceAll(std::string(scenarios.status().message()), {{path, name}}));
  json out = {{"file", name}, {"scenarios", json::array()}};
  for (const ss::Scenario& s : *scenarios) {
    const KnownScenario* log = gw.scenario(s.id);
    out["scenarios"].push_back(scenario_json(s, log ? &log->scenario : nullptr));
  }
  spdlog::info("viewer: decoded '{}': {} scenarios", name, scenarios->size());
  return send(conn, 200, out.dump());
}

// One browser watching one session: a thread reads the session's WatchSession stream and writes each tick to the
// WebSocket. A slow browser slows only this thread; the server drops the oldest ticks of a watcher 64 behind.
struct Watcher {
  Gateway* gw = nullptr;
  mg_connection* conn = nullptr;
  std::mutex mu;
  bool closed = false;
  bool started = false;
  grpc::ClientContext ctx;
  std::thread thread;

  bool write(const std::string& text) {
    std::lock_guard<std::mutex> l(mu);
    if (closed) return false;
    mg_lock_connection(conn);
    const int n = mg_websocket_write(conn, MG_WEBSOCKET_OPCODE_TEXT, text.data(), text.size());
    mg_unlock_connection(conn);
    return n > 0;
  }

  void fail(const std::string& message) {
    spdlog::info("viewer: watch: {}", message);
    write(json{{"type", "error"}, {"message", message}}.dump());
  }

  void run(std::string session, std::string token) {
    grpc::ClientContext get_ctx;
    prepare(&get_ctx, token);
    pb::GetSessionRequest get;
    get.set_session_id(session);
    pb::GetSessionResponse info;
    const grpc::Status st = gw->stub().GetSession(&get_ctx, get, &info);
    if (!st.ok()) return fail(rpc_error(*gw, "GetSession", st));
    const KnownScenario* known = gw->scenario(info.info().scenario_name());
    static const ss::EventMap kNoMap;
    const ss::EventMap& event_map = known ? known->event_map : kNoMap;
    write(json{{"type", "session"}, {"session", session_json(info.info())}, {"map", known != nullptr}}.dump());

    if (!token.empty()) ctx.AddMetadata("authorization", "Bearer " + token);
    pb::WatchSessionRequest req;
    req.set_session_id(session);
    std::unique_ptr<grpc::ClientReader<pb::Tick>> reader = gw->stub().WatchSession(&ctx, req);
    // The stream begins with the session's current tick, so the page draws at once even when nobody steps it.
    ss::StepResult before;
    pb::Tick tick;
    while (reader->Read(&tick)) {
      ss::StepResult after = step_result_of(tick);
      if (!write(tick_json(tick, event_flags(event_map, before, after)).dump())) break;
      before = std::move(after);
    }
    const grpc::Status end = reader->Finish();
    {
      std::lock_guard<std::mutex> l(mu);
      if (closed) return;  // the browser went away: nothing to tell
    }
    if (end.ok() || end.error_code() == grpc::CANCELLED)
      write(json{{"type", "end"}, {"message", absl::StrCat("session '", session, "' closed")}}.dump());
    else
      fail(rpc_error(*gw, "WatchSession", end));
  }
};

int ws_connect(const mg_connection* conn, void* data) {
  auto* w = new Watcher;
  w->gw = static_cast<Gateway*>(data);
  mg_set_user_connection_data(conn, w);
  return 0;
}

void ws_ready(mg_connection* conn, void*) {
  static_cast<Watcher*>(mg_get_user_connection_data(conn))->conn = conn;
}

int ws_data(mg_connection* conn, int bits, char* data, size_t len, void*) {
  auto* w = static_cast<Watcher*>(mg_get_user_connection_data(conn));
  const int opcode = bits & 0xf;
  if (opcode == MG_WEBSOCKET_OPCODE_CONNECTION_CLOSE) return 0;
  if (opcode != MG_WEBSOCKET_OPCODE_TEXT || w->started) return 1;
  w->conn = conn;
  const auto parsed = ss::json_parse_strict(std::string_view(data, len), {.max_depth = 4});
  const json msg = parsed.ok() ? *parsed : json();
  std::string session, token;
  if (msg.is_object() && msg.contains("session") && msg["session"].is_string()) session = msg["session"];
  if (msg.is_object() && msg.contains("token") && msg["token"].is_string()) token = msg["token"];
  if (session.empty()) {
    w->fail("the first message on /ws/watch must be {\"session\": ID, \"token\": TOKEN or \"\"}");
    return 1;
  }
  if (!token_ok(token)) {
    w->fail("the token holds a character other than letters, digits and -._~+/=, or is longer than 512");
    return 1;
  }
  w->started = true;
  w->thread = std::thread(&Watcher::run, w, session, token);
  return 1;
}

void ws_close(const mg_connection* conn, void*) {
  auto* w = static_cast<Watcher*>(mg_get_user_connection_data(conn));
  if (!w) return;
  {
    std::lock_guard<std::mutex> l(w->mu);
    w->closed = true;
  }
  w->ctx.TryCancel();
  if (w->thread.joinable()) w->thread.join();
  delete w;
}

int log_message(const mg_connection*, const char* message) {
  spdlog::warn("viewer: civetweb: {}", message);
  return 1;
}

}  // namespace

bool token_ok(const std::string& token) {
  if (token.size() > 512) return false;
  for (char c : token)
    if (!std::isalnum(static_cast<unsigned char>(c)) && !std::strchr("-._~+/=", c)) return false;
  return true;
}

Gateway::Gateway(std::shared_ptr<grpc::Channel> channel, std::string target,
                 std::map<std::string, std::shared_ptr<const KnownScenario>> scenarios, GatewayOptions options)
    : channel_(std::move(channel)),
      stub_(scenestreamer::v1::Simulator::NewStub(channel_)),
      target_(std::move(target)),
      scenarios_(std::move(scenarios)),
      options_(std::move(options)) {}

Gateway::~Gateway() { stop(); }

const KnownScenario* Gateway::scenario(const std::string& name) const {
  const auto it = scenarios_.find(name);
  return it == scenarios_.end() ? nullptr : it->second.get();
}

absl::Status Gateway::start() {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(std::filesystem::path(options_.web_dir) / "index.html", ec))
    return absl::NotFoundError(absl::StrCat("--web_dir ", options_.web_dir, " holds no index.html (the page's build, "
                                            "viewer/web/dist)"));
  const bool tls = !options_.tls_cert.empty();
  if (tls != !options_.tls_key.empty()) return absl::InvalidArgumentError("--tls_cert and --tls_key go together");
  if (tls) {
    if (!mg_check_feature(2)) return absl::FailedPreconditionError("this civetweb library was built without TLS");
    // Before civetweb opens "libssl.so" (viewer/openssl3_shim.c says why): beside the program.
    const std::filesystem::path shim = std::filesystem::read_symlink("/proc/self/exe", ec).parent_path() / "libss-viewer-ssl.so";
    if (!dlopen(shim.c_str(), RTLD_NOW | RTLD_GLOBAL))
      return absl::NotFoundError(absl::StrCat("HTTPS needs ", shim.string(), " (built beside the viewer): ", dlerror()));
    // civetweb reads the key and the certificate chain from one PEM file: the two, joined, readable by us only.
    std::string pem;
    for (const std::string& f : {options_.tls_key, options_.tls_cert}) {
      std::ifstream in(f);
      if (!in) return absl::NotFoundError(absl::StrCat(f == options_.tls_key ? "--tls_key " : "--tls_cert ", f,
                                                       ": cannot read it"));
      std::stringstream ss;
      ss << in.rdbuf();
      pem += ss.str() + "\n";
    }
    pem_path_ = (std::filesystem::temp_directory_path() / "ss-viewer-tls-XXXXXX").string();
    const int fd = mkstemp(pem_path_.data());
    if (fd < 0) return absl::InternalError(absl::StrCat("cannot make a temporary file: ", std::strerror(errno)));
    const bool ok = ::write(fd, pem.data(), pem.size()) == static_cast<ssize_t>(pem.size());
    ::close(fd);
    if (!ok) return absl::InternalError("cannot write the TLS file");
  }
  const std::string ports = absl::StrCat(options_.host, ":", options_.port, tls ? "s" : "");
  const std::string threads = std::to_string(options_.threads);
  std::vector<const char*> opts = {"listening_ports", ports.c_str(), "document_root", options_.web_dir.c_str(),
                                   "num_threads", threads.c_str(), "enable_directory_listing", "no",
                                   "enable_websocket_ping_pong", "yes", "websocket_timeout_ms", "3600000"};
  if (tls) {
    opts.insert(opts.end(), {"ssl_certificate", pem_path_.c_str(), "ssl_protocol_version", "4"});  // TLS 1.2 and up
  }
  opts.push_back(nullptr);
  mg_callbacks callbacks{};
  callbacks.log_message = log_message;
  mg_init_library(tls ? MG_FEATURES_TLS : 0);
  char error_text[256] = "";
  unsigned error_code = 0;
  mg_init_data init{&callbacks, this, opts.data()};
  mg_error_data error{&error_code, error_text, sizeof error_text};
  ctx_ = mg_start2(&init, &error);
  if (!ctx_)
    return absl::UnavailableError(absl::StrCat("cannot serve the viewer on ", options_.host, ":", options_.port, ": ",
                                               error_text[0] ? error_text : "civetweb refused to start"));
  mg_set_request_handler(ctx_, "/api/sessions$", handle_sessions, this);
  mg_set_request_handler(ctx_, "/api/map$", handle_map, this);
  mg_set_request_handler(ctx_, "/api/rollout$", handle_rollout, this);
  mg_set_websocket_handler(ctx_, "/ws/watch$", ws_connect, ws_ready, ws_data, ws_close, this);
  mg_server_port p[4];
  const int n = mg_get_server_ports(ctx_, 4, p);
  port_ = n > 0 ? p[0].port : options_.port;
  return absl::OkStatus();
}

void Gateway::stop() {
  if (ctx_) mg_stop(ctx_);
  ctx_ = nullptr;
  if (!pem_path_.empty()) std::filesystem::remove(pem_path_);
  pem_path_.clear();
}

}  // namespace viewer
