# CPU flags: Cortex-M4 with the single-precision FPU (FPv4-SP-D16), hard-float ABI, Thumb-2.
# Used by both MCU boards (STM32G474 and the QEMU mps2-an386). Included by the toolchain file so that the
# compiler probes and every target see the same flags (the multilib selection at link time depends on them).
set(PHALANX_CPU_FLAGS -mcpu=cortex-m4 -mfpu=fpv4-sp-d16 -mfloat-abi=hard -mthumb)
string(JOIN " " _phalanx_cpu_flags ${PHALANX_CPU_FLAGS})
set(CMAKE_C_FLAGS_INIT "${_phalanx_cpu_flags}")
set(CMAKE_CXX_FLAGS_INIT "${_phalanx_cpu_flags}")
set(CMAKE_ASM_FLAGS_INIT "${_phalanx_cpu_flags}")
set(CMAKE_EXE_LINKER_FLAGS_INIT "${_phalanx_cpu_flags}")
