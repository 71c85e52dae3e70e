#include "phalanx/sim/board.h"

#include <algorithm>
#include <cmath>

namespace phalanx::sim {

size_t ByteFifo::push(const uint8_t* src, size_t len) {
  const size_t n = std::min(len, space());
  for (size_t i = 0; i < n; ++i) buf_[(head_ + size_ + i) % kCapacity] = src[i];
  size_ += n;
  return n;
}

size_t ByteFifo::pop(uint8_t* dst, size_t max_len) {
  const size_t n = std::min(max_len, size_);
  for (size_t i = 0; i < n; ++i) dst[i] = buf_[(head_ + i) % kCapacity];
  head_ = (head_ + n) % kCapacity;
  size_ -= n;
  return n;
}

SimBoard::SimBoard(uint8_t pwm_count, uint8_t adc_count, uint8_t encoder_count, hal::ByteLink& link)
    : pwm_(io_, pwm_count), adc_(io_, adc_count), enc_(io_, encoder_count), gpio_(io_) {
  board_.clock = &clock_;
  board_.pwm = &pwm_;
  board_.adc = &adc_;
  board_.encoders = &enc_;
  board_.gpio = &gpio_;
  board_.link = &link;
}

void SimBoard::Pwm::setDuty(uint8_t ch, float duty) {
  if (ch >= n_ || !std::isfinite(duty)) return;
  io_.pwm_duty[ch] = std::clamp(duty, -1.0f, 1.0f);
  io_.pwm_enabled = true;
}

void SimBoard::Pwm::disableAll() {
  io_.pwm_enabled = false;
  io_.pwm_duty.fill(0.0f);
}

}  // namespace phalanx::sim
