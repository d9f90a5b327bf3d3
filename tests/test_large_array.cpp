// Tests of ice/large_array.h: buffers of 2 MiB and more are 2 MiB-aligned (what huge pages need),
// smaller ones come from std::allocator; growing across the threshold, copying and moving keep the
// contents.
#include <catch2/catch.hpp>

#include <cstdint>
#include <numeric>

#include "ice/large_array.h"

TEST_CASE("large arrays: aligned when large, contents kept across the threshold", "[large_array]") {
  constexpr std::size_t kAlignment = std::size_t{1} << 21;
  ice::LargeArray<std::int64_t> values(1000);
  std::iota(values.begin(), values.end(), 0);
  const std::size_t large = ice::detail::kLargeArrayBytes / sizeof(std::int64_t) + 123;
  values.resize(large, -1);  // crosses from std::allocator to the large path
  CHECK(reinterpret_cast<std::uintptr_t>(values.data()) % kAlignment == 0);
  for (std::size_t i = 0; i < 1000; ++i) REQUIRE(values[i] == static_cast<std::int64_t>(i));
  CHECK(values.back() == -1);
  ice::LargeArray<std::int64_t> copy = values;
  CHECK(copy == values);
  CHECK(reinterpret_cast<std::uintptr_t>(copy.data()) % kAlignment == 0);
  ice::LargeArray<std::int64_t> moved = std::move(copy);
  CHECK(moved == values);
  moved.resize(10);
  moved.shrink_to_fit();  // back below the threshold
  CHECK(moved.size() == 10);
  CHECK(moved[9] == 9);
}
