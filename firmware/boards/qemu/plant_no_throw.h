#pragma once
// Force-included (-include) into the simulated plant's translation units when they are built for the emulated
// board. Why: hal/sim/src/glove_plant.cpp validates its configuration with `throw std::invalid_argument(...)`
// and `throw std::out_of_range(...)` (its contract on Linux), and GCC rejects `throw` under -fno-exceptions.
// Compiling the plant with -fexceptions would link libstdc++'s exception classes, whose constructors build a
// std::string on the heap (malloc), plus the unwinder and the verbose terminate handler (stdio). Instead, after
// every standard header the plant uses has been read with the real keyword, `throw E(args)` is redefined to a
// call of phalanx_plant_throw() followed by an unevaluated `sizeof E(args)`: no exception object, no library
// code. The plant's configuration is fixed and valid in the image, so the call never happens; if it did, the
// board stops with its outputs safe. The plant's files are not modified.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

extern "C" [[noreturn]] void phalanx_plant_throw(const char* file, int line);

// NOLINTNEXTLINE: redefining a keyword is deliberate and confined to the plant's translation units.
#define throw phalanx_plant_throw(__FILE__, __LINE__), (void)sizeof
