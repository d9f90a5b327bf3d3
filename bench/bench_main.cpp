// ice_bench's entry point: Google Benchmark's usual main, after the allocator setting the solving
// tools use (ice::keep_freed_memory_for_reuse, ice/large_array.h), so that every benchmark — ICE and
// the baselines (CHOLMOD, BoomerAMG, OpenMesh) alike, all in this one process — runs with freed
// memory reused instead of re-faulted. The context line of the output says whether it took.
#include <benchmark/benchmark.h>

#include "ice/large_array.h"

int main(int argc, char** argv) {
  const bool kept = ice::keep_freed_memory_for_reuse();
  benchmark::AddCustomContext("malloc", kept ? "glibc malloc keeps freed memory for reuse (mallopt accepted)" : "default");
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
