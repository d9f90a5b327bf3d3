// The main() of one tool's executable; ICE_TOOL names the tool's namespace (apps/CMakeLists.txt).
#include "tool_main.h"

int main(int argc, char** argv) { return ICE_TOOL::main(argc, argv); }
