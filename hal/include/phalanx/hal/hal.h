#pragma once
/// Hardware abstraction interfaces. The firmware core and the device apps talk to hardware only through these;
/// each backend (hal/sim, hal/mcu/...) implements them. Freestanding: no heap, no exceptions.
#include <cstddef>
#include <cstdint>

namespace phalanx::hal {

/// Monotonic microsecond clock.
class Clock {
 public:
  virtual ~Clock() = default;
  virtual uint64_t nowUs() const = 0;
};

/// H-bridge PWM outputs, one channel per motor. Duty in [-1, 1]; the sign selects the bridge direction.
class PwmOutputs {
 public:
  virtual ~PwmOutputs() = default;
  virtual uint8_t count() const = 0;
  virtual void setDuty(uint8_t channel, float duty) = 0;
  /// Safe state: every bridge off (high impedance) at once. Must be callable from a fault handler.
  virtual void disableAll() = 0;
};

/// ADC channels, raw counts (the backend documents the resolution; values are not scaled here).
class AdcInputs {
 public:
  virtual ~AdcInputs() = default;
  virtual uint8_t count() const = 0;
  virtual int32_t read(uint8_t channel) const = 0;
};

/// Quadrature encoders, accumulated counts.
class Encoders {
 public:
  virtual ~Encoders() = default;
  virtual uint8_t count() const = 0;
  virtual int32_t read(uint8_t channel) const = 0;
};

/// Digital lines. Inputs: e-stop (true = pressed, fail-safe). Outputs: drive enable.
class Gpio {
 public:
  virtual ~Gpio() = default;
  virtual bool estopPressed() const = 0;
  virtual void setDriveEnable(bool enabled) = 0;
};

/// Byte stream to the host (UART, USB CDC, pty). Non-blocking: both calls return what they could move now.
class ByteLink {
 public:
  virtual ~ByteLink() = default;
  virtual size_t read(uint8_t* dst, size_t max_len) = 0;
  virtual size_t write(const uint8_t* src, size_t len) = 0;
  /// Bytes that write() can accept now without splitting; the core only writes whole frames.
  virtual size_t writeSpace() const = 0;
};

/// Counters of frames a packet transport rejected before they became messages.
struct PacketRxStats {
  uint32_t bad_id = 0;      ///< unknown identifier/function, other node, wrong direction
  uint32_t bad_length = 0;  ///< length or format differs from the mapping
  uint32_t crc = 0;         ///< end-to-end CRC failed
  uint32_t sequence = 0;    ///< a multi-frame message out of order or incomplete
  uint32_t total() const { return bad_id + bad_length + crc + sequence; }
};

/// Message-per-packet link (CAN-FD, classic CAN through its compact mapping, USB bulk): the transport maps and
/// checks whole protocol messages, the endpoint never sees framing. Non-blocking, like ByteLink.
class PacketLink {
 public:
  virtual ~PacketLink() = default;
  /// Send one protocol message (payload of exactly its wire size). Never blocks; false when the transport cannot
  /// take all of it now (queue full, link down, not representable): then nothing of it is sent.
  virtual bool send(uint8_t msg_id, const uint8_t* payload, size_t len) = 0;
  /// Take the next received message that passed the transport's checks; payload must hold 64 bytes.
  /// Returns false when none is pending.
  virtual bool receive(uint8_t& msg_id, uint8_t* payload, size_t& len) = 0;
  virtual PacketRxStats rxStats() const = 0;
};

/// The hardware one device app needs, gathered so the core can hand it over in one piece.
struct Board {
  Clock* clock = nullptr;
  PwmOutputs* pwm = nullptr;
  AdcInputs* adc = nullptr;
  Encoders* encoders = nullptr;
  Gpio* gpio = nullptr;
  ByteLink* link = nullptr;
  PacketLink* packets = nullptr;  ///< when set, the protocol runs over this instead of link
};

}  // namespace phalanx::hal
