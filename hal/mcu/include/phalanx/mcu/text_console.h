#pragma once
/// Polled text output for boot, safe-state and statistics lines (never on the protocol link), over any UART
/// that can send one character: Port provides init(base) and put(char) (a bounded wait for room, then the byte).
/// Bounded loops throughout: a string is cut at 256 characters.
#include <cstdint>

namespace phalanx::mcu {

template <class Port>
class TextConsole {
 public:
  void init(uint32_t base) { port_.init(base); }
  TextConsole& str(const char* s) {
    for (int i = 0; i < 256 && s[i] != 0; ++i) port_.put(s[i]);
    return *this;
  }
  TextConsole& u64(uint64_t v) {
    char buf[21];
    int i = 20;
    buf[i] = 0;
    do {
      buf[--i] = static_cast<char>('0' + v % 10u);
      v /= 10u;
    } while (v != 0 && i > 0);
    return str(buf + i);
  }
  TextConsole& u32(uint32_t v) { return u64(v); }
  TextConsole& i32(int32_t v) {
    if (v < 0) str("-");
    return u64(v < 0 ? 0u - static_cast<uint32_t>(v) : static_cast<uint32_t>(v));
  }
  TextConsole& hex16(uint16_t v) {
    constexpr char kDigits[] = "0123456789abcdef";
    const char buf[7] = {'0', 'x', kDigits[(v >> 12) & 0xF], kDigits[(v >> 8) & 0xF], kDigits[(v >> 4) & 0xF],
                         kDigits[v & 0xF], 0};
    return str(buf);
  }
  TextConsole& end() { return str("\n"); }

 private:
  Port port_;
};

}  // namespace phalanx::mcu
