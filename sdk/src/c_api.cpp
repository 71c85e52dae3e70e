// The C ABI over the C++ API: opaque handle, error codes, a thread-local message.
#include <cstring>
#include <new>
#include <string>

#include "phalanx/client.hpp"
#include "phalanx/host/client/wire.h"

namespace {
thread_local std::string g_error;

int failed(int code, const std::string& why) {
  g_error = why;
  return code;
}

}  // namespace

struct phalanx_client {
  explicit phalanx_client(const phalanx::ConnectOptions& o) : client(o) {}
  phalanx::Client client;
};

extern "C" {

int phalanx_version(void) { return PHALANX_VERSION; }

const char* phalanx_last_error(void) { return g_error.c_str(); }

phalanx_client* phalanx_connect(const char* socket_path, unsigned deadline_ms, int fallback) {
  if (socket_path == nullptr || (fallback != PHALANX_FALLBACK_SAFE && fallback != PHALANX_FALLBACK_TRANSPARENT)) {
    failed(PHALANX_EARG, "phalanx_connect: socket_path is NULL or fallback is not PHALANX_FALLBACK_*");
    return nullptr;
  }
  phalanx::ConnectOptions o;
  o.socket_path = socket_path;
  o.deadline_ms = deadline_ms;
  o.fallback = static_cast<phalanx::Fallback>(fallback);
  try {
    return new phalanx_client(o);
  } catch (const phalanx::Error& e) {
    failed(e.code(), e.what());
  } catch (const std::bad_alloc&) {
    failed(PHALANX_EARG, "out of memory");
  }
  return nullptr;
}

void phalanx_disconnect(phalanx_client* c) { delete c; }

int phalanx_get_device_info(const phalanx_client* c, phalanx_device_info* out) {
  if (c == nullptr || out == nullptr) return failed(PHALANX_EARG, "phalanx_get_device_info: NULL argument");
  *out = c->client.device();
  return PHALANX_OK;
}

int phalanx_get_state(phalanx_client* c, phalanx_state* out) {
  if (c == nullptr || out == nullptr) return failed(PHALANX_EARG, "phalanx_get_state: NULL argument");
  return c->client.getState(*out) ? PHALANX_OK : failed(PHALANX_ETIMEOUT, "no state published yet");
}

int phalanx_wait_state(phalanx_client* c, phalanx_state* out, int timeout_ms) {
  if (c == nullptr || out == nullptr) return failed(PHALANX_EARG, "phalanx_wait_state: NULL argument");
  return c->client.waitState(*out, timeout_ms) ? PHALANX_OK : failed(PHALANX_ETIMEOUT, "no new state in time");
}

int phalanx_set_setpoints(phalanx_client* c, const float* setpoints, unsigned count, int mode) {
  if (c == nullptr || setpoints == nullptr) return failed(PHALANX_EARG, "phalanx_set_setpoints: NULL argument");
  if (count != c->client.device().setpoint_count) {
    return failed(PHALANX_EARG, "phalanx_set_setpoints: count " + std::to_string(count) + " != the device's " +
                                    std::to_string(c->client.device().setpoint_count));
  }
  phalanx::Command cmd;
  cmd.mode = static_cast<phalanx::Mode>(mode);
  for (unsigned i = 0; i < count; ++i) cmd.setpoint[i] = setpoints[i];
  c->client.setCommand(cmd);
  return PHALANX_OK;
}

int phalanx_glove_set_fingertip_forces(phalanx_client* c, const double force_N[PHALANX_GLOVE_FINGERS]) {
  if (c == nullptr || force_N == nullptr) return failed(PHALANX_EARG, "phalanx_glove_set_fingertip_forces: NULL argument");
  std::array<double, PHALANX_GLOVE_FINGERS> f{};
  for (size_t i = 0; i < f.size(); ++i) f[i] = force_N[i];
  return c->client.setFingertipForces(f) ? PHALANX_OK : failed(PHALANX_EARG, "not a glove5 device");
}

int phalanx_glove_fingertip(const phalanx_state* s, int finger, double pose[3]) {
  if (s == nullptr || pose == nullptr || finger < 0 || finger >= PHALANX_GLOVE_FINGERS) {
    return failed(PHALANX_EARG, "phalanx_glove_fingertip: NULL argument or finger not in 0..4");
  }
  const std::array<double, 3> u = phalanx::gloveFingertip(*s, finger);
  for (int i = 0; i < 3; ++i) pose[i] = u[static_cast<size_t>(i)];
  return PHALANX_OK;
}

int phalanx_run_servo(phalanx_client* c, phalanx_servo_fn fn, void* user, phalanx_state* last) {
  if (c == nullptr || fn == nullptr) return failed(PHALANX_EARG, "phalanx_run_servo: NULL argument");
  const int rc = c->client.runServo(
      [&](const phalanx::State& s, phalanx::Command& cmd) {
        cmd.mode = phalanx::Mode::kSetpoint;
        return fn(&s, cmd.setpoint.data(), user) == 0;
      },
      last);
  if (rc == PHALANX_EFORCED_OFF) return failed(rc, "the daemon forced this client off");
  return rc;
}

namespace {
phalanx::Command fromC(const phalanx_command& c) {
  phalanx::Command cmd;
  cmd.mode = static_cast<phalanx::Mode>(c.mode);
  cmd.kind = static_cast<phalanx::CommandKind>(c.kind);
  for (size_t i = 0; i < cmd.setpoint.size(); ++i) cmd.setpoint[i] = c.setpoint[i];
  for (size_t i = 0; i < cmd.model.size(); ++i) cmd.model[i] = c.model[i];
  cmd.fallback = c.fallback;
  return cmd;
}
void toC(const phalanx::Command& cmd, phalanx_command& c) {
  c.mode = static_cast<int>(cmd.mode);
  c.kind = static_cast<int>(cmd.kind);
  for (size_t i = 0; i < cmd.setpoint.size(); ++i) c.setpoint[i] = cmd.setpoint[i];
  for (size_t i = 0; i < cmd.model.size(); ++i) c.model[i] = cmd.model[i];
  c.fallback = cmd.fallback;
}
}  // namespace

int phalanx_set_command(phalanx_client* c, const phalanx_command* cmd) {
  if (c == nullptr || cmd == nullptr) return failed(PHALANX_EARG, "phalanx_set_command: NULL argument");
  // The daemon validates everything (kind for the device, finite values, k and b >= 0) and counts refusals.
  c->client.set(fromC(*cmd));
  return PHALANX_OK;
}

int phalanx_sea_set_finger_torques(phalanx_client* c, const double tau_Nm[2], const phalanx_fallback_spring* fallback) {
  if (c == nullptr || tau_Nm == nullptr) return failed(PHALANX_EARG, "phalanx_sea_set_finger_torques: NULL argument");
  return c->client.setFingerTorques(tau_Nm[0], tau_Nm[1], fallback) ? PHALANX_OK
                                                                     : failed(PHALANX_EARG, "not a sea_finger device");
}

int phalanx_pen_set_wrench(phalanx_client* c, const double force_N[3], const double torque_Nm[3],
                           const phalanx_fallback_spring* fallback) {
  if (c == nullptr || force_N == nullptr) return failed(PHALANX_EARG, "phalanx_pen_set_wrench: NULL argument");
  std::array<double, 3> f{force_N[0], force_N[1], force_N[2]}, t{};
  if (torque_Nm != nullptr) t = {torque_Nm[0], torque_Nm[1], torque_Nm[2]};
  return c->client.setPenWrench(f, t, fallback) ? PHALANX_OK : failed(PHALANX_EARG, "not a pantograph device");
}

int phalanx_run_servo_command(phalanx_client* c, phalanx_servo_command_fn fn, void* user, phalanx_state* last) {
  if (c == nullptr || fn == nullptr) return failed(PHALANX_EARG, "phalanx_run_servo_command: NULL argument");
  phalanx_command cc{};
  cc.mode = PHALANX_MODE_SETPOINT;
  const int rc = c->client.runServo(
      [&](const phalanx::State& s, phalanx::Command& cmd) {
        const bool go = fn(&s, &cc, user) == 0;
        cmd = fromC(cc);
        return go;
      },
      last);
  (void)toC;
  if (rc == PHALANX_EFORCED_OFF) return failed(rc, "the daemon forced this client off");
  return rc;
}

const char* phalanx_force_off_cause_name(int cause) {
  if (cause < 0 || cause > PHALANX_CAUSE_DAEMON_STOP) return "unknown";
  return phalanx::client_wire::forceOffCauseName(static_cast<phalanx::client_wire::ForceOffCause>(cause));
}

}  // extern "C"
