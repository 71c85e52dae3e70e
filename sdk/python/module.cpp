// phalanx._phalanx: the Python bindings of libphalanx (pybind11), docs/sdk.md §"Python".
// Arrays are returned as numpy float64 arrays built with numpy.frombuffer from a copy - deliberately no numpy
// C API, so one module works with Debian's numpy 1.x and a newer numpy 2.x alike (the Python ABI is the same).
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <array>
#include <cstring>
#include <string>
#include <vector>

#include "phalanx/client.hpp"
#ifdef PHALANX_NETWORK
#include "phalanx/network.hpp"
#endif

namespace py = pybind11;

namespace {

py::object asArray(const float* p, size_t n, std::vector<py::ssize_t> shape) {
  static py::object* frombuffer = new py::object(py::module_::import("numpy").attr("frombuffer"));  // never freed
  std::vector<double> d(p, p + n);
  py::bytes b(reinterpret_cast<const char*>(d.data()), n * sizeof(double));
  py::object a = (*frombuffer)(b, "float64");
  if (shape.size() > 1) a = a.attr("reshape")(py::tuple(py::cast(shape)));
  return a;
}

const char* controlName(int c) {
  switch (c) {
    case PHALANX_CONTROL_NOT_YET: return "not-yet";
    case PHALANX_CONTROL_CLIENT: return "client";
    case PHALANX_CONTROL_OTHER_SOURCE: return "other-source";
    case PHALANX_CONTROL_FORCED_OFF: return "forced-off";
    case PHALANX_CONTROL_STOPPED: return "stopped";
    default: return "unknown";
  }
}

const char* renderedName(int r) {
  switch (r) {
    case PHALANX_RENDERED_COMMAND: return "command";
    case PHALANX_RENDERED_FALLBACK_SPRING: return "fallback-spring";
    case PHALANX_RENDERED_REPEAT: return "repeat";
    default: return "nothing";
  }
}

/// fallback: None, or a sequence of (target, stiffness, damping) - target a sequence of up to 3 numbers.
phalanx::FallbackSpring fallbackFrom(const py::object& spec) {
  phalanx::FallbackSpring fb{};
  if (spec.is_none()) return fb;
  const auto elems = spec.cast<std::vector<py::sequence>>();
  if (elems.size() > PHALANX_MAX_SPRINGS) throw py::value_error("fallback: at most 5 springs");
  fb.enabled = 1;
  for (size_t i = 0; i < elems.size(); ++i) {
    if (elems[i].size() != 3) throw py::value_error("fallback: each spring is (target, stiffness, damping)");
    const auto target = elems[i][0].cast<std::vector<double>>();
    if (target.size() > 3) throw py::value_error("fallback: a target has at most 3 coordinates");
    for (size_t k = 0; k < target.size(); ++k) fb.element[i].target[k] = static_cast<float>(target[k]);
    fb.element[i].stiffness = elems[i][1].cast<float>();
    fb.element[i].damping = elems[i][2].cast<float>();
  }
  return fb;
}

std::array<double, 3> vec3(const py::object& o, const char* what) {
  const auto v = o.cast<std::vector<double>>();
  if (v.size() != 3) throw py::value_error(std::string(what) + ": 3 values expected");
  return {v[0], v[1], v[2]};
}

#ifdef PHALANX_NETWORK
py::dict deviceDict(const phalanx::NetworkDevice& d) {
  py::dict o;
  o["host"] = d.host;
  o["name"] = d.name;
  o["type"] = d.type;
  o["device"] = d.spec;
  o["state"] = d.state;
  o["rate_hz"] = d.rate_hz;
  o["firmware_build_id"] = d.firmware_build_id;
  o["commands"] = d.commands;
  o["age_s"] = d.age_s;
  return o;
}

void sendOrRaise(phalanx::RemoteDevice& r, const phalanx::Command& cmd) {
  if (!r.send(cmd)) throw std::runtime_error("RemoteDevice: " + r.lastError());
}

/// libphalanx's network part (docs/sdk.md "Devices on the network").
void bindNetwork(py::module_& m) {
  m.def("network_devices", [](unsigned domain, const std::string& interface, double seconds) {
    phalanx::NetworkOptions o;
    o.domain = domain;
    o.interface = interface;
    o.discovery_s = seconds;
    std::vector<phalanx::NetworkDevice> seen;
    {
      py::gil_scoped_release nogil;
      seen = phalanx::listNetworkDevices(o);
    }
    py::list out;
    for (const auto& d : seen) out.append(deviceDict(d));
    return out;
  }, py::arg("domain") = 0, py::arg("interface") = "", py::arg("seconds") = 2.0,
     "Every device the daemons announce over DDS within `seconds` (as `phalanx devices`).");
  py::class_<phalanx::RemoteDevice>(m, "RemoteDevice")
      .def(py::init([](const std::string& name, unsigned domain, const std::string& interface, double discovery_s,
                       const std::string& host) {
             phalanx::NetworkOptions o;
             o.domain = domain;
             o.interface = interface;
             o.discovery_s = discovery_s;
             o.host = host;
             py::gil_scoped_release nogil;
             return std::make_unique<phalanx::RemoteDevice>(name, o);
           }),
           py::arg("name"), py::arg("domain") = 0, py::arg("interface") = "", py::arg("discovery_s") = 2.0,
           py::arg("host") = "")
      .def_property_readonly("device", [](const phalanx::RemoteDevice& r) { return deviceDict(r.device()); })
      .def("set_setpoints", [](phalanx::RemoteDevice& r, const std::vector<double>& sp, const std::string& mode) {
        if (sp.size() != r.setpointCount()) {
          throw py::value_error("setpoints: " + std::to_string(r.setpointCount()) + " values for a " + r.device().type);
        }
        phalanx::Command cmd;
        cmd.mode = mode == "transparent" ? phalanx::Mode::kTransparent : phalanx::Mode::kSetpoint;
        for (size_t i = 0; i < sp.size(); ++i) cmd.setpoint[i] = static_cast<float>(sp[i]);
        sendOrRaise(r, cmd);
      }, py::arg("setpoints"), py::arg("mode") = "setpoint", "Raw per-channel setpoints (SI), the device's count.")
      .def("set_pen_wrench", [](phalanx::RemoteDevice& r, const py::object& force, const py::object& torque) {
        phalanx::Command cmd;
        cmd.penWrench(vec3(force, "force"), torque.is_none() ? std::array<double, 3>{} : vec3(torque, "torque"));
        sendOrRaise(r, cmd);
      }, py::arg("force"), py::arg("torque") = py::none())
      .def("set_finger_torques", [](phalanx::RemoteDevice& r, double mcp, double pip) {
        phalanx::Command cmd;
        cmd.fingerTorques(mcp, pip);
        sendOrRaise(r, cmd);
      }, py::arg("mcp"), py::arg("pip"))
      .def("wait_joints", [](phalanx::RemoteDevice& r, int timeout_ms) -> py::object {
        phalanx::RemoteJoints j;
        bool ok = false;
        {
          py::gil_scoped_release nogil;
          ok = r.waitJoints(j, timeout_ms);
        }
        if (!ok) return py::none();
        py::dict o;
        o["name"] = j.name;
        o["position"] = j.position;
        o["velocity"] = j.velocity;
        o["effort"] = j.effort;
        o["stamp_ns"] = j.stamp_ns;
        return o;
      }, py::arg("timeout_ms") = 100, "The next joint_states sample as a dict (None on timeout).")
      .def("release", &phalanx::RemoteDevice::release);
}
#endif

}  // namespace

namespace {

/// State: what the daemon publishes each cycle (docs/sdk.md "State").
void bindState(py::module_& m) {
  py::class_<phalanx::State>(m, "State")
      .def_readonly("cycle", &phalanx::State::cycle)
      .def_readonly("daemon_time_ns", &phalanx::State::daemon_time_ns)
      .def_readonly("telemetry_rx_ns", &phalanx::State::telemetry_rx_ns)
      .def_readonly("device_time_us", &phalanx::State::device_time_us)
      .def_readonly("telemetry_seq", &phalanx::State::telemetry_seq)
      .def_readonly("device_mode", &phalanx::State::device_mode)
      .def_readonly("fault_bits", &phalanx::State::fault_bits)
      .def_property_readonly("control", [](const phalanx::State& s) { return controlName(s.control); })
      .def_property_readonly("force_off_cause",
                             [](const phalanx::State& s) { return phalanx_force_off_cause_name(s.force_off_cause); })
      .def_property_readonly("rendered", [](const phalanx::State& s) { return renderedName(s.rendered); })
      .def_readonly("commands_used", &phalanx::State::commands_used)
      .def_readonly("command_seq_used", &phalanx::State::command_seq_used)
      .def_readonly("refused_invalid", &phalanx::State::refused_invalid)
      .def_readonly("refused_other_source", &phalanx::State::refused_other_source)
      .def_readonly("limited", &phalanx::State::limited)
      .def_readonly("force_offs", &phalanx::State::force_offs)
      .def_readonly("model_saturated", &phalanx::State::model_saturated)
      .def_readonly("fallback_cycles", &phalanx::State::fallback_cycles)
      .def_readonly("model_scale", &phalanx::State::model_scale)
      .def_readonly("achieved_rate_hz", &phalanx::State::achieved_rate_hz)
      .def_property_readonly("sample", [](const phalanx::State& s) { return asArray(s.sample, PHALANX_MAX_SAMPLES, {}); })
      .def_property_readonly("setpoint_sent",
                             [](const phalanx::State& s) { return asArray(s.setpoint_sent, PHALANX_MAX_SETPOINTS, {}); })
      // glove5
      .def_property_readonly("glove_valid", [](const phalanx::State& s) {
        std::vector<bool> v(s.glove.valid, s.glove.valid + 5);
        return v;
      })
      .def_property_readonly("glove_joint_rad", [](const phalanx::State& s) { return asArray(&s.glove.joint_rad[0][0], 15, {5, 3}); })
      .def_property_readonly("glove_fingertip", [](const phalanx::State& s) { return asArray(&s.glove.fingertip[0][0], 15, {5, 3}); })
      .def_property_readonly("glove_fingertip_velocity",
                             [](const phalanx::State& s) { return asArray(&s.glove.fingertip_velocity[0][0], 10, {5, 2}); })
      .def_property_readonly("glove_pad_force", [](const phalanx::State& s) { return asArray(s.glove.pad_force_N, 5, {}); })
      // sea_finger
      .def_property_readonly("sea_valid", [](const phalanx::State& s) { return s.sea.valid != 0; })
      .def_property_readonly("sea_flexion", [](const phalanx::State& s) { return asArray(s.sea.flexion_rad, 3, {}); })
      .def_property_readonly("sea_flexion_rate", [](const phalanx::State& s) { return asArray(s.sea.flexion_rate_rad_s, 3, {}); })
      .def_property_readonly("sea_finger_torque", [](const phalanx::State& s) { return asArray(s.sea.finger_torque_Nm, 2, {}); })
      .def_property_readonly("sea_exo_torque", [](const phalanx::State& s) { return asArray(s.sea.exo_torque_Nm, 2, {}); })
      // pantograph
      .def_property_readonly("pen_valid", [](const phalanx::State& s) { return s.pen.valid != 0; })
      .def_property_readonly("pen_centre", [](const phalanx::State& s) { return asArray(s.pen.centre_m, 3, {}); })
      .def_property_readonly("pen_axis", [](const phalanx::State& s) { return asArray(s.pen.axis, 3, {}); })
      .def_property_readonly("pen_tip", [](const phalanx::State& s) { return asArray(s.pen.tip_m, 3, {}); })
      .def_property_readonly("pen_angles", [](const phalanx::State& s) {
        const float a[2] = {s.pen.theta_x_rad, s.pen.theta_z_rad};
        return asArray(a, 2, {});
      })
      .def_property_readonly("pen_velocity", [](const phalanx::State& s) { return asArray(s.pen.velocity_m_s, 3, {}); })
      .def_property_readonly("pen_force", [](const phalanx::State& s) { return asArray(s.pen.force_N, 3, {}); })
      .def_property_readonly("pen_torque", [](const phalanx::State& s) { return asArray(s.pen.torque_Nm, 3, {}); });
}

/// Client: the local client channel (connect, read state, command).
void bindClient(py::module_& m) {
  py::class_<phalanx::Client>(m, "Client")
      .def(py::init([](const std::string& socket, unsigned deadline_ms, const std::string& fallback) {
             if (fallback != "safe" && fallback != "transparent") {
               throw py::value_error("fallback: 'safe' or 'transparent'");
             }
             phalanx::ConnectOptions o;
             o.socket_path = socket;
             o.deadline_ms = deadline_ms;
             o.fallback = fallback == "safe" ? phalanx::Fallback::kSafe : phalanx::Fallback::kTransparent;
             return std::make_unique<phalanx::Client>(o);
           }),
           py::arg("socket"), py::arg("deadline_ms") = 20, py::arg("fallback") = "safe")
      .def_property_readonly("device", [](const phalanx::Client& c) {
        const auto& d = c.device();
        py::dict out;
        out["name"] = std::string(d.device_name);
        out["type"] = d.device_type;
        out["setpoint_count"] = d.setpoint_count;
        out["sample_count"] = d.sample_count;
        out["setpoint_limit"] = d.setpoint_limit;
        out["rate_hz"] = d.rate_hz;
        out["deadline_ms"] = d.deadline_ms;
        out["firmware_build_id"] = d.firmware_build_id;
        return out;
      })
      .def("get_state", [](phalanx::Client& c) -> py::object {
        phalanx::State s{};
        if (!c.getState(s)) return py::none();
        return py::cast(s);
      })
      .def("wait_state", [](phalanx::Client& c, int timeout_ms) -> py::object {
        phalanx::State s{};
        bool ok = false;
        {
          py::gil_scoped_release nogil;  // the wait sleeps on the daemon's futex
          ok = c.waitState(s, timeout_ms);
        }
        if (!ok) return py::none();
        return py::cast(s);
      }, py::arg("timeout_ms") = 100, "The next state (None on timeout).")
      .def("set_setpoints", [](phalanx::Client& c, const std::vector<double>& sp, const std::string& mode) {
        if (sp.size() != c.device().setpoint_count) throw py::value_error("setpoints: the device's setpoint_count values");
        phalanx::Command cmd;
        cmd.mode = mode == "transparent" ? phalanx::Mode::kTransparent : mode == "safe" ? phalanx::Mode::kSafe
                                                                                         : phalanx::Mode::kSetpoint;
        for (size_t i = 0; i < sp.size(); ++i) cmd.setpoint[i] = static_cast<float>(sp[i]);
        c.set(cmd);
      }, py::arg("setpoints"), py::arg("mode") = "setpoint", "Raw per-channel setpoints (the bench's access).")
      .def("set_pen_wrench", [](phalanx::Client& c, const py::object& force, const py::object& torque,
                                const py::object& fallback) {
        phalanx::Command cmd;
        cmd.penWrench(vec3(force, "force"), torque.is_none() ? std::array<double, 3>{} : vec3(torque, "torque"));
        cmd.fallback = fallbackFrom(fallback);
        if (c.device().device_type != 3) throw py::value_error("set_pen_wrench: not a pantograph");
        c.set(cmd);
      }, py::arg("force"), py::arg("torque") = py::none(), py::arg("fallback") = py::none(),
         "Wrench at the pen centre (N, N·m, base frame). fallback: [(centre_target, k_N_per_m, b_N_s_per_m)].")
      .def("set_finger_torques", [](phalanx::Client& c, double mcp, double pip, const py::object& fallback) {
        phalanx::Command cmd;
        cmd.fingerTorques(mcp, pip);
        cmd.fallback = fallbackFrom(fallback);
        if (c.device().device_type != 2) throw py::value_error("set_finger_torques: not a sea_finger");
        c.set(cmd);
      }, py::arg("mcp"), py::arg("pip"), py::arg("fallback") = py::none(),
         "SEA finger joint torques (N·m, + extends). fallback: [((mcp_flex,), k, b), ((pip_flex,), k, b)].")
      .def("set_fingertip_forces", [](phalanx::Client& c, const std::vector<std::vector<double>>& f,
                                      const py::object& fallback) {
        if (f.size() != 5) throw py::value_error("fingertip forces: 5 fingers of (fx, fy)");
        std::array<std::array<double, 2>, 5> v{};
        for (size_t i = 0; i < 5; ++i) {
          if (f[i].size() != 2) throw py::value_error("fingertip forces: (fx, fy) per finger");
          v[i] = {f[i][0], f[i][1]};
        }
        phalanx::Command cmd;
        cmd.fingertipForces(v);
        cmd.fallback = fallbackFrom(fallback);
        if (c.device().device_type != 1) throw py::value_error("set_fingertip_forces: not a glove5");
        c.set(cmd);
      }, py::arg("forces"), py::arg("fallback") = py::none(),
         "glove5: force (fx, fy) on each fingertip in its base frame, N. fallback: [((x, y), k, b)] per finger.")
      .def("achieved_rate_hz", &phalanx::Client::achievedRateHz)
      .def("release", &phalanx::Client::release);
}

}  // namespace

PYBIND11_MODULE(_phalanx, m) {
  m.doc() = "libphalanx bindings: connect to phalanxd's client channel, read state, command (docs/sdk.md)";
  m.attr("VERSION") = PHALANX_VERSION;

  bindState(m);
  py::register_exception<phalanx::Error>(m, "Error", PyExc_RuntimeError);
  bindClient(m);
#ifdef PHALANX_NETWORK
  bindNetwork(m);
#endif
}
