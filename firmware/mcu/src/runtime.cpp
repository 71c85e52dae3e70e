// Minimal C++ run-time for the MCU images: what the compiler and libstdc++ headers reference, implemented so
// that nothing pulls the heap, stdio or the exception machinery from the libraries. Every "cannot happen" path
// goes to the board's phalanx_fatal(), which turns the power stage off first.
#include <bits/functexcept.h>

#include <cstddef>

extern "C" [[noreturn]] void phalanx_fatal(const char* why);

// Static objects are never destroyed on the firmware (it never returns from main), so their destructors are
// not registered: this keeps newlib's atexit table out of RAM.
extern "C" int __aeabi_atexit(void*, void (*)(void*), void*) { return 0; }
void* __dso_handle = nullptr;

extern "C" void __cxa_pure_virtual() { phalanx_fatal("pure virtual call"); }

// Virtual destructors make the compiler emit deleting destructors that reference operator delete; no object
// is ever deleted (all are static), so reaching one is a fault. operator new is deliberately not defined: any
// use of it is a link error instead of a silent heap.
void operator delete(void*) noexcept { phalanx_fatal("operator delete"); }
void operator delete(void*, std::size_t) noexcept { phalanx_fatal("operator delete"); }

// libstdc++ headers (std::array::at, containers) call these on misuse; the library versions construct
// exception objects on the heap. Here they are faults.
namespace std {
void __throw_bad_alloc() { phalanx_fatal("bad_alloc"); }
void __throw_bad_array_new_length() { phalanx_fatal("bad_array_new_length"); }
void __throw_length_error(const char*) { phalanx_fatal("length_error"); }
void __throw_logic_error(const char*) { phalanx_fatal("logic_error"); }
void __throw_invalid_argument(const char*) { phalanx_fatal("invalid_argument"); }
void __throw_out_of_range(const char*) { phalanx_fatal("out_of_range"); }
void __throw_out_of_range_fmt(const char*, ...) { phalanx_fatal("out_of_range"); }
void __throw_bad_function_call() { phalanx_fatal("bad_function_call"); }
}  // namespace std

// newlib's abort() would try to raise a signal through stdio-backed stubs.
extern "C" void abort() { phalanx_fatal("abort"); }
