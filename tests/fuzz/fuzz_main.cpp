// One libFuzzer target per input kind: ICE_FUZZ_INPUT names it (tests/fuzz/CMakeLists.txt).
#include "fuzz_harness.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  ice_fuzz::check_input(ice_fuzz::Input::ICE_FUZZ_INPUT, data, size);
  return 0;
}
