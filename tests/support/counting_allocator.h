#pragma once
/// Counting allocator for allocation-free checks: replaces every global operator new/delete of the test binary
/// that includes this header (include it from exactly one source file per binary). `g_allocations` counts calls
/// to operator new since start-up; a test reads it before and after the code that must not allocate.
#include <atomic>
#include <cstdlib>
#include <new>

namespace phalanx_test {
inline std::atomic<long> g_allocations{0};
// noinline: keeps GCC's -Wmismatched-new-delete from pairing the inlined malloc/free with new/delete.
[[gnu::noinline]] inline void* countedAlloc(std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  return std::malloc(n == 0 ? 1 : n);
}
[[gnu::noinline]] inline void* countedAlignedAlloc(std::size_t n, std::align_val_t al) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  const std::size_t a = static_cast<std::size_t>(al);
  return std::aligned_alloc(a, (n + a - 1) / a * a);
}
[[gnu::noinline]] inline void countedFree(void* p) { std::free(p); }
}  // namespace phalanx_test

using phalanx_test::g_allocations;

void* operator new(std::size_t n) {
  if (void* p = phalanx_test::countedAlloc(n)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) {
  if (void* p = phalanx_test::countedAlloc(n)) return p;
  throw std::bad_alloc();
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return phalanx_test::countedAlloc(n); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return phalanx_test::countedAlloc(n); }
void* operator new(std::size_t n, std::align_val_t al) {
  if (void* p = phalanx_test::countedAlignedAlloc(n, al)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n, std::align_val_t al) {
  if (void* p = phalanx_test::countedAlignedAlloc(n, al)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { phalanx_test::countedFree(p); }
void operator delete[](void* p) noexcept { phalanx_test::countedFree(p); }
void operator delete(void* p, std::size_t) noexcept { phalanx_test::countedFree(p); }
void operator delete[](void* p, std::size_t) noexcept { phalanx_test::countedFree(p); }
void operator delete(void* p, std::align_val_t) noexcept { phalanx_test::countedFree(p); }
void operator delete[](void* p, std::align_val_t) noexcept { phalanx_test::countedFree(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { phalanx_test::countedFree(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { phalanx_test::countedFree(p); }
