// Loading a large mesh: ICE's readers plus the validation every tool runs, beside OpenMesh's reader
// (which builds its half-edge mesh but validates nothing), on the same files in the same run.
//
//   ice_bench --benchmark_filter='BM_(LoadMesh|OpenMeshRead)' --benchmark_repetitions=5
//             --benchmark_enable_random_interleaving=true --benchmark_report_aggregates_only=true
//   (one command line)
#include <cstdio>
#include <filesystem>
#include <string>
#include <unistd.h>

#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>

#include "bench_support.h"

namespace {

namespace fs = std::filesystem;

const char* const kFormats[] = {"off", "obj", "ply", "binary.ply"};

/// spot_subdiv Loop-subdivided three times (1,584,194 vertices) written once per process in each
/// format, into a folder removed at exit.
class LargeMeshFiles {
 public:
  LargeMeshFiles() : dir_(fs::temp_directory_path() / ("ice_bench_io_" + std::to_string(::getpid()))) {}
  ~LargeMeshFiles() {
    std::error_code ignored;
    fs::remove_all(dir_, ignored);
  }
  const std::string& path(int format) {
    if (paths_.empty()) {
      fs::create_directories(dir_);
      const ice::TriangleMesh& mesh = ice_bench::subdivided_mesh("spot_subdiv.obj", 3);
      for (const char* name : kFormats) {
        ice::WriteOptions options;
        options.binary = std::string(name) == "binary.ply";
        paths_.push_back((dir_ / ("spot3." + std::string(name))).string());
        ice::write_mesh(paths_.back(), mesh, options);
      }
    }
    return paths_[static_cast<std::size_t>(format)];
  }

 private:
  fs::path dir_;
  std::vector<std::string> paths_;
};

LargeMeshFiles& files() {
  static LargeMeshFiles instance;
  return instance;
}

void BM_LoadMesh(benchmark::State& state) {
  const std::string& path = files().path(static_cast<int>(state.range(0)));
  state.SetLabel(kFormats[state.range(0)]);
  std::size_t vertices = 0;
  for (auto _ : state) {
    const ice::LoadResult loaded = ice::load_mesh_with_report(path);  // read + validate, as the tools do
    vertices = static_cast<std::size_t>(loaded.mesh.V.rows());
    benchmark::DoNotOptimize(loaded.report.clean());
  }
  state.counters["vertices"] = static_cast<double>(vertices);
}
BENCHMARK(BM_LoadMesh)->DenseRange(0, 3)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);

void BM_OpenMeshRead(benchmark::State& state) {
  const std::string& path = files().path(static_cast<int>(state.range(0)));
  state.SetLabel(kFormats[state.range(0)]);
  std::size_t vertices = 0;
  for (auto _ : state) {
    OpenMesh::TriMesh_ArrayKernelT<> mesh;
    OpenMesh::IO::Options options;
    if (state.range(0) == 3) options += OpenMesh::IO::Options::Binary;
    if (!OpenMesh::IO::read_mesh(mesh, path, options)) state.SkipWithError(("OpenMesh cannot read " + path).c_str());
    vertices = mesh.n_vertices();
  }
  state.counters["vertices"] = static_cast<double>(vertices);
}
BENCHMARK(BM_OpenMeshRead)->DenseRange(0, 3)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);

}  // namespace
