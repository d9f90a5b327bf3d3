#include "fuzz_harness.h"

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <stdexcept>

#include <unistd.h>

#include "app_common.h"
#include "ice/intrinsic_mesh_io.h"
#include "ice/intrinsic_triangulation.h"
#include "ice/mesh_io.h"

namespace ice_fuzz {
namespace {

[[noreturn]] void finding(const std::string& what) {
  std::fprintf(stderr, "FUZZ FINDING: %s\n", what.c_str());
  std::fflush(stderr);
  std::abort();
}

/// A loaded mesh the loader accepted must triangulate: the report and the triangulation share
/// their criteria (one-criterion rule of mesh_validation.h).
void require_triangulates(const ice::LoadResult& loaded, const char* how) {
  try {
    const auto T = ice::IntrinsicTriangulation::from_mesh(loaded.mesh.V, loaded.mesh.F);
    const std::string problems = T.validate();
    if (!problems.empty()) finding(std::string(how) + ": accepted mesh, invalid triangulation: " + problems);
  } catch (const std::exception& e) {
    finding(std::string(how) + ": accepted mesh, triangulation refused it: " + e.what());
  }
}

void check_file(Input kind, const std::string& path) {
  if (kind == Input::numbers) {
    try {
      app::read_number_file(path);
    } catch (const app::AppError&) {
    }
    return;
  }
  if (kind == Input::ilm) {
    ice::IntrinsicMeshFile file;
    try {
      file = ice::read_intrinsic_mesh(path);
    } catch (const ice::MeshError&) {
      return;
    }
    try {
      const ice::IntrinsicTriangulation T = ice::triangulation_of(file, path);
      const std::string problems = T.validate();
      if (!problems.empty()) finding("ilm: triangulation built but invalid: " + problems);
    } catch (const ice::MeshError&) {
    }
    return;
  }
  for (bool repair : {false, true}) {
    try {
      const ice::LoadResult loaded = ice::load_mesh_with_report(path, {repair, false});
      require_triangulates(loaded, repair ? "with --repair" : "without repair");
    } catch (const ice::MeshError&) {
    }
  }
}

}  // namespace

const char* extension(Input kind) {
  switch (kind) {
    case Input::obj: return "obj";
    case Input::off: return "off";
    case Input::ply: return "ply";
    case Input::stl: return "stl";
    case Input::ilm: return "ilm";
    case Input::numbers: return "txt";
  }
  return "bin";
}

bool parse_kind(const std::string& name, Input& kind) {
  for (Input k : {Input::obj, Input::off, Input::ply, Input::stl, Input::ilm, Input::numbers})
    if (name == (k == Input::numbers ? "numbers" : extension(k))) {
      kind = k;
      return true;
    }
  return false;
}

void check_input(Input kind, const std::uint8_t* data, std::size_t size) {
  // One file per process, named with the kind's extension (the readers dispatch on it).
  static const std::string directory = [] {
    const char* tmp = std::getenv("TMPDIR");
    return std::string(tmp && *tmp ? tmp : "/tmp");
  }();
  const std::string path = directory + "/ice_fuzz_" + std::to_string(::getpid()) + "." + extension(kind);
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  try {
    check_file(kind, path);
  } catch (const std::exception& e) {
    std::remove(path.c_str());
    finding(std::string("unexpected exception: ") + e.what());
  }
  std::remove(path.c_str());
}

}  // namespace ice_fuzz
