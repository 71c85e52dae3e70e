// libFuzzer target: the session record reader (record/record_reader.cpp), bytes as a file would hold them.
#include <vector>

#include "fuzz_util.h"
#include "phalanx/host/record/record_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::vector<uint8_t> bytes(data, data + size);
  phalanx::host::record::SessionRecord rec;
  (void)phalanx::host::record::parseRecord(bytes, rec);
  return 0;
}
