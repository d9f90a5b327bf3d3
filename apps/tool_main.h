#pragma once
/// \file tool_main.h
/// Each tool's entry point: the tools' code is compiled into one library (ice_tools) so that the
/// command-line parser, a header-only library that costs several seconds of compiling per file, is
/// compiled once per batch instead of once per tool; each executable's main() (tool_main.cpp) calls
/// its tool's.

namespace geodesic_coarse_tool { int main(int argc, char** argv); }
namespace heat_coarse_tool { int main(int argc, char** argv); }
namespace ice_cache_tool { int main(int argc, char** argv); }
namespace ice_coarsen_tool { int main(int argc, char** argv); }
namespace ice_info_tool { int main(int argc, char** argv); }
namespace poisson_coarse_tool { int main(int argc, char** argv); }
namespace spectral_coarse_tool { int main(int argc, char** argv); }
namespace vector_coarse_tool { int main(int argc, char** argv); }
