#pragma once
// Shared by the libFuzzer targets: a parser's answer must be "" or an error message; an exception that escapes a
// parser of untrusted input is a finding (libFuzzer reports the abort with the input that caused it).
#include <cstddef>
#include <cstdint>
#include <string>

namespace phalanx::fuzz {

inline std::string text(const uint8_t* data, size_t size) { return std::string(reinterpret_cast<const char*>(data), size); }

}  // namespace phalanx::fuzz
