# Toolchain file: GNU Arm Embedded (arm-none-eabi-gcc from Debian's gcc-arm-none-eabi), bare metal.
# Only the compilers and how CMake probes them live here; the CPU flags are in a separate file named by
# PHALANX_CPU_FILE (cmake/cpu-cortex-m4f.cmake), as PX4 keeps Toolchain-arm-none-eabi.cmake apart from its
# per-CPU flag files.
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)

set(PHALANX_TOOLCHAIN_PREFIX arm-none-eabi- CACHE STRING "cross tool prefix")
find_program(CMAKE_C_COMPILER ${PHALANX_TOOLCHAIN_PREFIX}gcc REQUIRED)
find_program(CMAKE_CXX_COMPILER ${PHALANX_TOOLCHAIN_PREFIX}g++ REQUIRED)
set(CMAKE_ASM_COMPILER ${CMAKE_C_COMPILER})
find_program(PHALANX_OBJCOPY ${PHALANX_TOOLCHAIN_PREFIX}objcopy REQUIRED)
find_program(PHALANX_SIZE ${PHALANX_TOOLCHAIN_PREFIX}size REQUIRED)
find_program(PHALANX_NM ${PHALANX_TOOLCHAIN_PREFIX}nm REQUIRED)

# Compiler probes cannot link a bare-metal executable without a linker script.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)
set(CMAKE_TRY_COMPILE_PLATFORM_VARIABLES PHALANX_CPU_FILE PHALANX_TOOLCHAIN_PREFIX)

# Never pick up host libraries or headers.
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)

if(PHALANX_CPU_FILE)
  include(${PHALANX_CPU_FILE})
endif()
