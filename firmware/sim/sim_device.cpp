#include "phalanx/fw_sim/sim_device.h"

#include <stdexcept>

#include "phalanx/fw_sim/glove5_sim.h"
#include "phalanx/fw_sim/pantograph_sim.h"
#include "phalanx/fw_sim/sea_finger_sim.h"

namespace phalanx::fw_sim {
bool parseHandScenario(const std::string& name, sim::HandScenario& out) {
  if (name == "still") out = sim::HandScenario::kStill;
  else if (name == "close-open") out = sim::HandScenario::kCloseOpen;
  else if (name == "grasp") out = sim::HandScenario::kGrasp;
  else if (name == "random") out = sim::HandScenario::kRandom;
  else return false;
  return true;
}

bool parseSeaUserMotion(const std::string& name, sim::SeaUserMotion& out) {
  // The exoskeleton has no virtual objects to grasp: "grasp" (the CLI's default) is the relaxed finger too.
  if (name == "still" || name == "grasp") out = sim::SeaUserMotion::kRelaxed;
  else if (name == "random") out = sim::SeaUserMotion::kRandom;
  else if (name == "close-open") out = sim::SeaUserMotion::kCloseOpen;
  else if (name == "hold") out = sim::SeaUserMotion::kHold;
  else return false;
  return true;
}

std::unique_ptr<SimDevice> makeSimDevice(const std::string& name, const SimDeviceOptions& options, std::string& error) {
  if (name == "glove5") {
    sim::GlovePlantConfig cfg;
    cfg.seed = options.seed;
    cfg.noise = options.noise;
    if (!parseHandScenario(options.scenario, cfg.scenario)) {
      error = "unknown scenario '" + options.scenario + "' (still, close-open, grasp, random)";
      return nullptr;
    }
    try {
      return std::make_unique<Glove5SimDevice>(cfg);
    } catch (const std::invalid_argument& e) {
      error = std::string("glove plant configuration: ") + e.what();
      return nullptr;
    }
  }
  if (name == "sea_rig" || name == "sea_finger") {
    sim::SeaPlantConfig cfg;
    cfg.seed = options.seed;
    cfg.noise = options.noise;
    cfg.variant = name == "sea_rig" ? sim::SeaVariant::kRig : sim::SeaVariant::kFinger;
    if (options.scenario == "spastic" && name == "sea_finger") {
      // The relaxed finger with a stretch reflex (the instrumented Tardieu test's simulated patient).
      cfg.motion = sim::SeaUserMotion::kRelaxed;
      cfg.params.finger = sim::withStretchReflex(cfg.params.finger);
    } else if (!parseSeaUserMotion(options.scenario, cfg.motion)) {
      error = "unknown scenario '" + options.scenario + "' (still, close-open, grasp, random" +
              (name == "sea_finger" ? ", spastic)" : ")");
      return nullptr;
    }
    try {
      return std::make_unique<SeaFingerSimDevice>(cfg);
    } catch (const std::invalid_argument& e) {
      error = std::string("SEA plant configuration: ") + e.what();
      return nullptr;
    }
  }
  if (name == "pantograph") {
    sim::PenPlantConfig cfg;
    cfg.seed = options.seed;
    cfg.noise = options.noise;
    // The pen's hand: "still" and "grasp" hold the pen at home; "random" and "close-open" move it about.
    if (options.scenario == "still" || options.scenario == "grasp") cfg.scenario = sim::PenHandScenario::kHold;
    else if (options.scenario == "random" || options.scenario == "close-open") cfg.scenario = sim::PenHandScenario::kRandom;
    else if (options.scenario == "press") cfg.scenario = sim::PenHandScenario::kPress;
    else {
      error = "unknown scenario '" + options.scenario +
              "' (still, grasp: hold the pen; random, close-open: move it; press: push 3.5 cm along +x from 2 s on)";
      return nullptr;
    }
    try {
      return std::make_unique<PantographSimDevice>(cfg);
    } catch (const std::invalid_argument& e) {
      error = std::string("pen plant configuration: ") + e.what();
      return nullptr;
    }
  }
  error = "unknown device '" + name + "' (glove5, sea_finger, sea_rig, pantograph)";
  return nullptr;
}

}  // namespace phalanx::fw_sim

namespace phalanx::fw_sim {
namespace {

const char* const kFingerNames[] = {"thumb", "index", "middle", "ring", "little"};
static_assert(sizeof kFingerNames / sizeof kFingerNames[0] == glove::board::kFingerCount, "one name per finger");

}  // namespace

// Per finger: the true pad-normal force, the planar wrench on the fingertip and the fingertip pose in {O}.
std::vector<std::string> Glove5SimDevice::truthColumns() const {
  std::vector<std::string> c;
  for (const char* f : kFingerNames) {
    const std::string n(f);
    for (const char* q : {"pad_force_", "tip_fx_", "tip_fy_"}) c.push_back(q + n + "_N");
    for (const char* q : {"tip_x_", "tip_y_"}) c.push_back(q + n + "_m");
    c.push_back("tip_phi_" + n + "_rad");
  }
  return c;
}

void Glove5SimDevice::truthValues(double* out) const {
  for (int i = 0; i < glove::board::kFingerCount; ++i) {
    const sim::GloveFingerTruth& t = plant_.truth(i);
    *out++ = t.pad_force_N;
    *out++ = t.O_F_tip[0];
    *out++ = t.O_F_tip[1];
    for (int k = 0; k < 3; ++k) *out++ = t.O_u_tip[k];
  }
}

// A force sensor under the index fingertip pad (the finger a grasp test presses with).
std::string Glove5SimDevice::instrumentSignal() const { return "pad_force_index_N"; }

// Per SEA (MCP, PIP): the torque it applies to its exoskeleton joint and what the rig's load cell reads; on the
// finger the finger joint torques (J_n^-T tau_j, 001 eq 9) and the finger's joint angles.
std::vector<std::string> SeaFingerSimDevice::truthColumns() const {
  std::vector<std::string> c;
  for (const char* j : {"mcp", "pip"}) {
    c.push_back(std::string("sea_torque_") + j + "_Nm");
    c.push_back(std::string("load_cell_") + j + "_Nm");
    c.push_back(std::string("finger_torque_") + j + "_Nm");
  }
  for (const char* j : {"mcp", "pip", "dip"}) c.push_back(std::string("finger_angle_") + j + "_rad");
  // The stretch reflex's share of the finger's torque (0 unless the simulated patient is spastic).
  for (const char* j : {"mcp", "pip"}) c.push_back(std::string("finger_reflex_") + j + "_Nm");
  return c;
}

void SeaFingerSimDevice::truthValues(double* out) const {
  for (int s = 0; s < 2; ++s) {
    *out++ = plant_.truth(s).joint_torque_Nm;
    *out++ = plant_.truth(s).load_cell_torque_Nm;
    *out++ = plant_.finger().applied_Nm[static_cast<size_t>(s)];
  }
  for (double a : plant_.finger().theta_rad) *out++ = a;
  for (double r : plant_.finger().reflex_Nm) *out++ = r;
}

// The rig (§7.1): the MCP load cell, the reference instrument its benches score against (SEA 0). On the finger
// there is no load cell: a joint torque transducer on the MCP SEA's output.
std::string SeaFingerSimDevice::instrumentSignal() const {
  return plant_.config().variant == sim::SeaVariant::kRig ? "load_cell_mcp_Nm" : "sea_torque_mcp_Nm";
}

// The six motor torques after the amplifier (what the joints receive), the pen pose x = (c, theta_x, theta_z) and the
// hand's grip force on the pen centre.
std::vector<std::string> PantographSimDevice::truthColumns() const {
  std::vector<std::string> c;
  for (int j = 0; j < 6; ++j) c.push_back("motor_torque" + std::to_string(j) + "_Nm");
  for (const char* q : {"x_m", "y_m", "z_m", "theta_x_rad", "theta_z_rad"}) c.push_back(std::string("pen_") + q);
  for (const char* q : {"x", "y", "z"}) c.push_back(std::string("hand_force_") + q + "_N");
  return c;
}

void PantographSimDevice::truthValues(double* out) const {
  const sim::PenTruth& t = plant_.truth();
  for (double v : t.motor_torque_Nm) *out++ = v;
  for (double v : t.x) *out++ = v;
  for (double v : t.hand_force_N) *out++ = v;
}

// A force sensor in the pen's handle: the grip force along x, the axis of the box's first wall (pen-wall bench).
std::string PantographSimDevice::instrumentSignal() const { return "hand_force_x_N"; }

}  // namespace phalanx::fw_sim
