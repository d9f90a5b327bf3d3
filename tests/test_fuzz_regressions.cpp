// Every input the fuzz targets found (tests/fuzz/regressions/<kind>/), and hand-made inputs that
// exercised fixed reader defects, replayed through the fuzz harness: a crash, a sanitizer report or
// any other finding fails this test (scripts/fuzz.sh says how to add one).
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "fuzz/fuzz_harness.h"

namespace fs = std::filesystem;

TEST_CASE("fuzz regressions: every saved input is refused cleanly or read correctly", "[fuzz][io]") {
  const fs::path root = fs::path(ICE_SOURCE_DIR) / "tests" / "fuzz" / "regressions";
  REQUIRE(fs::is_directory(root));
  int replayed = 0;
  for (const auto& directory : fs::directory_iterator(root)) {
    ice_fuzz::Input kind;
    REQUIRE(ice_fuzz::parse_kind(directory.path().filename().string(), kind));
    for (const auto& entry : fs::directory_iterator(directory.path())) {
      INFO(entry.path().string());
      std::ifstream in(entry.path(), std::ios::binary);
      const std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      ice_fuzz::check_input(kind, reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
      ++replayed;
    }
  }
  CHECK(replayed > 0);
}
