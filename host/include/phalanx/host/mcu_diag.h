#pragma once
/// Reads an MCU board's diagnostic parameters (0x0080–0x0089: control-tick statistics, overruns, plant time,
/// receive overflows; firmware/mcu/include/phalanx/fw_mcu/board_diag.h) through the wire protocol: handshake, then
/// one ParamGet per parameter. `phalanx mcu-diag --device serial:/dev/pts/N` prints them; tools/mcu/qemu_board.py
/// bench compares them with the firmware's own STATS line.
#include <cstdint>
#include <map>
#include <string>

#include <nlohmann/json.hpp>

#include "phalanx/protocol/messages.h"

namespace phalanx::linux_hal {
class FdLink;
}

namespace phalanx::host {

class HostSession;

/// Handshakes with a board on an open link: Hello (expecting `expected`, kAny for any device) every 500 ms until the
/// board answers or `timeout_s` passes (a board whose link is backed up may miss the first Hello). Returns "" once
/// the handshake succeeded (session.deviceInfo() is the board's HelloAck), else why not. `what` names the link.
std::string handshakeBoard(linux_hal::FdLink& link, HostSession& session, double timeout_s,
                           protocol::DeviceType expected, const std::string& what);

/// Opens the serial device at `path`, handshakes (any device type) and reads every board diagnostic parameter.
/// Returns a JSON object {device_type, firmware: {build_id (hex git hash), protocol_version, tick_rate_hz},
/// params: {name: value}}: counts are integers; tick figures are in units of params.tick_unit_ns (QEMU -icount:
/// 2^shift ns = one instruction; QEMU in real time: one SysTick count, 40 ns on mps2-an386; STM32: 5.88 ns = one
/// CPU cycle). On failure an empty object, and `error` says why.
/// A device without the parameters (firmware-sim, a non-MCU build) answers "unknown parameter": reported as an error.
nlohmann::json readMcuDiagnostics(const std::string& path, double timeout_s, std::string& error);

/// The JSON readMcuDiagnostics prints, from the handshake's answer and the parameters read (id → value; the
/// protocol carries every parameter as an f32, the counts are printed as the integers they are).
nlohmann::json mcuDiagJson(const std::string& device_type, const protocol::HelloAck& ack,
                           const std::map<uint16_t, float>& values);

}  // namespace phalanx::host
