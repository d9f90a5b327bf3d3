#pragma once
/// What the fuzz targets check (tests/fuzz/): the bytes of one input are written to a file and read
/// the way the tools read a user's file. The documented refusal (ice::MeshError, app::AppError) is a
/// pass; anything else is a finding and aborts: a crash or sanitizer report, another exception, a
/// mesh the report calls clean that the triangulation refuses, an .ilm whose triangulation builds but
/// does not validate. The same function replays saved findings in the test suite
/// (test_fuzz_regressions.cpp), so every finding stays a regression test.
#include <cstddef>
#include <cstdint>
#include <string>

namespace ice_fuzz {

enum class Input { obj, off, ply, stl, ilm, numbers };

/// File extension of an input kind ("obj", ..., "ilm", "txt" for numbers).
const char* extension(Input kind);
/// The kind named by a directory of tests/fuzz/regressions ("obj", ..., "numbers"); false if none.
bool parse_kind(const std::string& name, Input& kind);
/// Checks one input; aborts (after printing what happened) on a finding.
void check_input(Input kind, const std::uint8_t* data, std::size_t size);

}  // namespace ice_fuzz
