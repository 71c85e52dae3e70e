#pragma once
/// ARM semihosting as QEMU traps it (-semihosting-config enable=on): the emulated boards' command line, exit
/// status and settings flash file (semihost_flash.h). Shared by both emulated boards (mps2-an386, ast1030-evb); never linked into the STM32 image.
#include <cstdint>

namespace phalanx::mcu {

// ARM semihosting (ARM DUI 0471 "Semihosting operations"), trapped by QEMU with -semihosting-config.
constexpr uint32_t kSysOpen = 0x01;   ///< {name, mode, strlen(name)} -> handle or -1
constexpr uint32_t kSysWrite = 0x05;  ///< {handle, data, n} -> bytes NOT written
constexpr uint32_t kSysRead = 0x06;   ///< {handle, data, n} -> bytes NOT read
constexpr uint32_t kSysSeek = 0x0A;   ///< {handle, absolute position} -> 0 or negative
constexpr uint32_t kSysWriteC = 0x03;
constexpr uint32_t kSysReadC = 0x07;
constexpr uint32_t kSysGetCmdline = 0x15;
constexpr uint32_t kSysExit = 0x18;
constexpr uint32_t kAdpStoppedApplicationExit = 0x20026;  ///< QEMU exits with status 0
constexpr uint32_t kAdpStoppedRunTimeError = 0x20023;     ///< QEMU exits with status 1

inline int32_t semihost(uint32_t op, const void* arg) {
  register uint32_t r0 __asm("r0") = op;
  register const void* r1 __asm("r1") = arg;
  __asm volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
  return static_cast<int32_t>(r0);
}

}  // namespace phalanx::mcu
