#!/usr/bin/env bash
# Cross-build every MCU image (STM32G474 and the QEMU mps2-an386 and ast1030-evb boards) with warnings as errors. Each image's
# link fails when it exceeds its flash/RAM budget or links an allocator; the size reports are printed.
# Usage: tools/mcu/build.sh            (images in build/mcu-stm32g474, build/mcu-mps2-an386, build/mcu-ast1030)
set -euo pipefail
cd "$(dirname "$0")/../.."
for preset in mcu-stm32g474 mcu-mps2-an386 mcu-ast1030; do
  echo "== $preset =="
  cmake -S firmware/mcu --preset "$preset" >/dev/null
  cmake --build "build/$preset" -j2
done
echo "== size reports =="
cat build/mcu-stm32g474/*.size.txt build/mcu-mps2-an386/*.size.txt build/mcu-ast1030/*.size.txt
