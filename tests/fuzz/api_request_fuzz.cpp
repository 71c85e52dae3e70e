// libFuzzer target: the control API's JSON requests (api/server.cpp, the handler the UNIX socket and the
// dashboard share), one request line per input. Profiles are read from config/profiles; the records directory
// does not exist, so a start that passes every check is refused when its record cannot be created (no session
// thread, nothing written). Every answer must be an object with a boolean "ok", and an error when not ok.
#include "fuzz_util.h"
#include "phalanx/host/api/server.h"

using namespace phalanx::host;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const auto handle = [] {
    api::ServerConfig cfg;
    cfg.profiles_dir = PHALANX_SOURCE_DIR "/config/profiles";
    cfg.records_dir = "/nonexistent/phalanx-fuzz-records";
    cfg.defaults.device = "sim:glove5";
    cfg.allowed_devices = {"sim:sea_finger", "sim:pantograph"};
    return api::makeRequestHandler(cfg);
  }();
  const nlohmann::json r = handle(phalanx::fuzz::text(data, size));
  if (!r.is_object() || !r.contains("ok") || !r["ok"].is_boolean()) __builtin_trap();
  if (!r["ok"].get<bool>() && (!r.contains("error") || !r["error"].is_string())) __builtin_trap();
  if (r["ok"].get<bool>() && r.contains("result") && r["result"].is_object() && r["result"].contains("record")) {
    __builtin_trap();  // a session was started: the records directory cannot exist
  }
  return 0;
}
