// Receive-throughput probe for the emulated Cortex-M4 boards' UART models (tools/mcu/uart-throughput.sh; results
// in docs/firmware-mcu.md "The emulated UART's throughput"). Not firmware: a minimal bare-metal guest that counts
// the bytes its link UART receives (interrupt driven, draining everything the model holds per interrupt) while
// optionally sending TXLOAD bytes per 1 ms SysTick (the firmware's telemetry is 70), and prints
// "T <ms> <rx bytes> <tx bytes>" on its console UART every 500 ms.
// Boards: BOARD_MPS2 (mps2-an386, CMSDK UART0/UART1), BOARD_STM32 (netduinoplus2, STM32F405 USART1/USART2),
// BOARD_AST (ast1030-evb, 16550 UART5/UART1, FIFO trigger level FCRTRIG 0..3 = 1, 4, 8, 14 bytes).
#include <cstdint>

namespace {
inline volatile uint32_t& R(uint32_t a) { return *reinterpret_cast<volatile uint32_t*>(a); }
inline void readAndDiscard(uint32_t a) {
  const uint32_t v = R(a);
  static_cast<void>(v);
}
volatile uint32_t g_ms = 0, g_rx = 0, g_tx = 0;

#if defined(BOARD_MPS2)
constexpr uint32_t kLink = 0x40004000u, kCon = 0x40005000u, kClk = 25000000u, kRxIrq = 0;
void conPut(char c) { while (R(kCon + 4) & 1u) {} R(kCon) = static_cast<uint8_t>(c); }
void linkInit() { R(kLink + 0x10) = 16; R(kLink + 8) = 1u | 2u | 8u; }
void conInit() { R(kCon + 0x10) = 16; R(kCon + 8) = 1u; }
bool txReady() { return (R(kLink + 4) & 1u) == 0; }
void tx(uint8_t b) { R(kLink) = b; }
void rxIrq() {
  R(kLink + 0xC) = 2u;
  while (R(kLink + 4) & 2u) { readAndDiscard(kLink); g_rx = g_rx + 1u; }
}
#elif defined(BOARD_STM32)
constexpr uint32_t kLink = 0x40011000u, kCon = 0x40004400u, kClk = 168000000u, kRxIrq = 37;
void conPut(char c) { while ((R(kCon) & 0x80u) == 0) {} R(kCon + 4) = static_cast<uint8_t>(c); }
void linkInit() { R(kLink + 0x0C) = (1u << 13) | 8u | 4u | 0x20u; }
void conInit() { R(kCon + 0x0C) = (1u << 13) | 8u; }
bool txReady() { return (R(kLink) & 0x80u) != 0; }
void tx(uint8_t b) { R(kLink + 4) = b; }
void rxIrq() {
  while (R(kLink) & 0x20u) { readAndDiscard(kLink + 4); g_rx = g_rx + 1u; }
}
#elif defined(BOARD_AST)
constexpr uint32_t kLink = 0x7E784000u, kCon = 0x7E783000u, kClk = 200000000u, kRxIrq = 8;
void conPut(char c) { while ((R(kCon + 0x14) & 0x20u) == 0) {} R(kCon) = static_cast<uint8_t>(c); }
void linkInit() {
  R(kLink + 0x0C) = 0x83u; R(kLink + 0) = 1u; R(kLink + 4) = 0u; R(kLink + 0x0C) = 0x03u;
  R(kLink + 0x08) = 0x07u | (FCRTRIG << 6);
  R(kLink + 0x04) = 0x01u;
}
void conInit() { R(kCon + 0x0C) = 0x03u; R(kCon + 0x08) = 0x07u; }
bool txReady() { return (R(kLink + 0x14) & 0x20u) != 0; }
void tx(uint8_t b) { R(kLink) = b; }
void rxIrq() {
  readAndDiscard(kLink + 0x08);
  while (R(kLink + 0x14) & 1u) { readAndDiscard(kLink); g_rx = g_rx + 1u; }
}
#else
#error "define BOARD_MPS2, BOARD_STM32 or BOARD_AST"
#endif

void conStr(const char* s) { while (*s != 0) conPut(*s++); }
void conU32(uint32_t v) {
  char b[12];
  int i = 11;
  b[i] = 0;
  do { b[--i] = static_cast<char>('0' + v % 10u); v /= 10u; } while (v != 0);
  conStr(b + i);
}
}  // namespace

#ifndef TXLOAD
#define TXLOAD 0
#endif
constexpr int kTxLoad = TXLOAD;  // bytes sent per 1 ms tick (the firmware's telemetry frame: 70)

extern "C" uint32_t __stack_top__;
extern "C" void SysTick_Handler() {
  g_ms = g_ms + 1u;
  for (int i = 0; i < kTxLoad && txReady(); ++i) { tx(0x55); g_tx = g_tx + 1u; }
  if (g_ms % 500u == 0) {
    conStr("T "); conU32(g_ms); conStr(" "); conU32(g_rx); conStr(" "); conU32(g_tx); conStr("\n");
  }
}
extern "C" void Default_Handler() { for (;;) {} }
extern "C" void Reset_Handler();
extern "C" __attribute__((section(".vectors"), used)) void (*const g_vectors[16])() = {
    reinterpret_cast<void (*)()>(&__stack_top__), Reset_Handler, Default_Handler, Default_Handler,
    Default_Handler, Default_Handler, Default_Handler, nullptr, nullptr, nullptr, nullptr, Default_Handler,
    Default_Handler, nullptr, Default_Handler, SysTick_Handler};
extern "C" void RxIrq_Handler() { rxIrq(); }
extern "C" void Reset_Handler() {
  static void (*table[16 + 64])() __attribute__((aligned(512)));
  for (int i = 0; i < 16; ++i) table[i] = g_vectors[i];
  for (int i = 16; i < 80; ++i) table[i] = Default_Handler;
  table[16 + kRxIrq] = RxIrq_Handler;
  R(0xE000ED08u) = reinterpret_cast<uint32_t>(table);
  conInit();
  linkInit();
  conStr("BOOT probe\n");
  R(0xE000E100u + 4u * (kRxIrq / 32u)) = 1u << (kRxIrq % 32u);
  R(0xE000E014u) = kClk / 1000u - 1u;
  R(0xE000E018u) = 0;
  R(0xE000E010u) = 7u;
  for (;;) __asm volatile("wfi");
}
