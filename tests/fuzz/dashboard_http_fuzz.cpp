// libFuzzer target: the dashboard's HTTP request handling (api/dashboard.cpp): the bytes of one connection,
// served in memory by the same cpp-httplib server, pre-routing checks (Host, Origin, token) and routes
// (/, /dashboard.js, /api/samples, /api/request → the API's request handler) as on a socket. Host
// 127.0.0.1:0, token "f00d". cpp-httplib itself is Debian's shared library (not instrumented): the coverage
// and sanitizer checks are of the dashboard's code and the API handler behind it.
#include "fuzz_util.h"
#include "phalanx/host/api/dashboard.h"
#include "phalanx/host/api/server.h"

using namespace phalanx::host;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static api::Dashboard* dashboard = [] {
    api::ServerConfig cfg;
    cfg.profiles_dir = PHALANX_SOURCE_DIR "/config/profiles";
    cfg.records_dir = "/nonexistent/phalanx-fuzz-records";
    cfg.defaults.device = "sim:glove5";
    api::DashboardOptions opt;
    opt.enabled = true;
    opt.address = "127.0.0.1";
    opt.port = 0;
    return new api::Dashboard(opt, api::makeRequestHandler(cfg));
  }();
  const std::string out = dashboard->serveInMemory(phalanx::fuzz::text(data, size), "f00d");
  // Whatever came in, what goes out is HTTP responses.
  if (!out.empty() && out.rfind("HTTP/1.1 ", 0) != 0) __builtin_trap();
  return 0;
}
