#pragma once
/// A device's DDS topic namespace (docs/dds.md "Topics"), which is also the name it is addressed by on the
/// network: letters, digits, '_' and '/' between non-empty parts, not starting with a digit (ROS 2 names may not).
/// The daemon checks it in its config (dds.namespace), libphalanx in the name a client asks for.
#include <cctype>
#include <string_view>

namespace phalanx {

inline bool validDdsNamespace(std::string_view ns) {
  if (ns.empty() || ns.front() == '/' || ns.back() == '/' || ns.find("//") != std::string_view::npos) return false;
  if (std::isdigit(static_cast<unsigned char>(ns.front()))) return false;
  for (const char c : ns) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '/')) return false;
  }
  return true;
}

}  // namespace phalanx
