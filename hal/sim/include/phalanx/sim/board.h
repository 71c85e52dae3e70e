#pragma once
/// The simulated board: the hal interfaces implemented over a SimIo image and a virtual clock, plus an in-memory
/// byte pipe for lockstep runs. This is the first-class simulated backend the firmware core runs on.
#include <array>
#include <cstddef>
#include <cstdint>

#include "phalanx/hal/hal.h"
#include "phalanx/sim/plant.h"

namespace phalanx::sim {

/// Virtual microsecond clock, advanced explicitly.
class VirtualClock : public hal::Clock {
 public:
  uint64_t nowUs() const override { return now_us_; }
  void advanceUs(uint64_t dt_us) { now_us_ += dt_us; }

 private:
  uint64_t now_us_ = 0;
};

/// One direction of an in-memory byte link: a bounded FIFO (bytes beyond capacity are refused, like a full UART).
class ByteFifo {
 public:
  static constexpr size_t kCapacity = 16384;
  size_t push(const uint8_t* src, size_t len);
  size_t pop(uint8_t* dst, size_t max_len);
  size_t space() const { return kCapacity - size_; }
  size_t size() const { return size_; }

 private:
  std::array<uint8_t, kCapacity> buf_{};
  size_t head_ = 0;
  size_t size_ = 0;
};

/// A full-duplex in-memory link: end(0) and end(1) are the two peers.
class BytePipe {
 public:
  class End : public hal::ByteLink {
   public:
    End(ByteFifo& rx, ByteFifo& tx) : rx_(rx), tx_(tx) {}
    size_t read(uint8_t* dst, size_t max_len) override { return rx_.pop(dst, max_len); }
    size_t write(const uint8_t* src, size_t len) override { return tx_.push(src, len); }
    size_t writeSpace() const override { return tx_.space(); }

   private:
    ByteFifo& rx_;
    ByteFifo& tx_;
  };
  BytePipe() : a_(ab_rx_, ba_rx_), b_(ba_rx_, ab_rx_) {}
  End& end(int which) { return which == 0 ? a_ : b_; }

 private:
  ByteFifo ab_rx_;  // bytes for end 0 to read
  ByteFifo ba_rx_;  // bytes for end 1 to read
  End a_;
  End b_;
};

/// hal::Board over a SimIo image. The plant writes sensors into io(); the firmware's outputs land there too.
class SimBoard {
 public:
  SimBoard(uint8_t pwm_count, uint8_t adc_count, uint8_t encoder_count, hal::ByteLink& link);
  SimIo& io() { return io_; }
  VirtualClock& clock() { return clock_; }
  const VirtualClock& clock() const { return clock_; }
  hal::Board& board() { return board_; }

 private:
  class Pwm : public hal::PwmOutputs {
   public:
    Pwm(SimIo& io, uint8_t n) : io_(io), n_(n) {}
    uint8_t count() const override { return n_; }
    void setDuty(uint8_t ch, float duty) override;
    void disableAll() override;

   private:
    SimIo& io_;
    uint8_t n_;
  };
  class Adc : public hal::AdcInputs {
   public:
    Adc(SimIo& io, uint8_t n) : io_(io), n_(n) {}
    uint8_t count() const override { return n_; }
    int32_t read(uint8_t ch) const override { return ch < n_ ? io_.adc[ch] : 0; }

   private:
    SimIo& io_;
    uint8_t n_;
  };
  class Enc : public hal::Encoders {
   public:
    Enc(SimIo& io, uint8_t n) : io_(io), n_(n) {}
    uint8_t count() const override { return n_; }
    int32_t read(uint8_t ch) const override { return ch < n_ ? io_.encoder[ch] : 0; }

   private:
    SimIo& io_;
    uint8_t n_;
  };
  class Gpio : public hal::Gpio {
   public:
    explicit Gpio(SimIo& io) : io_(io) {}
    bool estopPressed() const override { return io_.estop_pressed; }
    void setDriveEnable(bool enabled) override { io_.drive_enable = enabled; }

   private:
    SimIo& io_;
  };

  SimIo io_;
  VirtualClock clock_;
  Pwm pwm_;
  Adc adc_;
  Enc enc_;
  Gpio gpio_;
  hal::Board board_;
};

}  // namespace phalanx::sim
