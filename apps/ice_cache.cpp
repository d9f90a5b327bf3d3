// ice-cache: look after the store of set-ups the tools and the Python package reuse (ice/proxy/store.h):
// list its entries, verify them, tell its size, clear it.
#include <algorithm>
#include <chrono>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "tool_main.h"
#include "command_line.h"
#include "ice/proxy/store.h"
#include "reports.h"

namespace ice_cache_tool {

const std::string kTool = "ice-cache";

// "2.5 MB" and friends.
std::string bytes_text(std::uint64_t bytes) {
  const char* units[] = {"B", "kB", "MB", "GB", "TB"};
  double value = static_cast<double>(bytes);
  int unit = 0;
  while (value >= 1000 && unit < 4) {
    value /= 1000;
    ++unit;
  }
  std::ostringstream out;
  out << std::fixed << std::setprecision(unit == 0 ? 0 : 1) << value << ' ' << units[unit];
  return out.str();
}

// How long ago `time` was, in words ("3 min ago").
std::string age_text(std::filesystem::file_time_type time) {
  const auto seconds = std::chrono::duration_cast<std::chrono::seconds>(std::filesystem::file_time_type::clock::now() - time).count();
  if (seconds < 120) return std::to_string(std::max<long long>(0, seconds)) + " s ago";
  if (seconds < 7200) return std::to_string(seconds / 60) + " min ago";
  if (seconds < 172800) return std::to_string(seconds / 3600) + " h ago";
  return std::to_string(seconds / 86400) + " days ago";
}

}  // namespace ice_cache_tool

int ice_cache_tool::main(int argc, char** argv) {
  CLI::App cli{
      "ice-cache: the store of set-ups that the tools and the Python package reuse, keyed by the mesh and the options:\n"
      "proxy (a coarse space and its proxy's operators), hierarchy (multigrid), space (a coarse space with its\n"
      "fine-to-coarse map), traced and curvature (what coarse marching reads beside a space), eigenpairs (a\n"
      "coarse pencil's eigenpairs, spectral-coarse). Default store:\n"
      "$ICE_CACHE, else $XDG_CACHE_HOME/ice, else ~/.cache/ice; size bound $ICE_CACHE_MAX_MB (default 4096).\n\n"
      "Examples:\n  ice-cache list\n  ice-cache verify --remove\n  ice-cache clear --cache /tmp/store\n\n"
      "Exit status: 0 ok (verify: every entry whole), 4 bad command line, 5 damaged entries found."};
  std::string directory;
  cli.add_option("--cache", directory, "The store's directory (default: see above)");
  cli.require_subcommand(1);
  cli.fallthrough();  // --cache after the subcommand too
  auto* list = cli.add_subcommand("list", "Entries, most recently used first: kind, key, size, last use");
  auto* verify = cli.add_subcommand("verify", "Check every entry (header, key, checksum, arrays)");
  bool remove_damaged = false;
  verify->add_flag("--remove", remove_damaged, "Remove the damaged entries");
  auto* size = cli.add_subcommand("size", "Entries, bytes in all and the size bound");
  auto* clear = cli.add_subcommand("clear", "Remove every entry");
  if (const int status = app::parse_command_line(cli, argc, argv); status >= 0) return status;

  return app::run_tool(kTool, [&] {
    const ice::proxy::Store store = app::store_at(directory);
    const ice::proxy::StoreOptions& options = store.options();
    if (!store.enabled()) throw app::AppError(app::kUsage, "no store: $ICE_CACHE is empty and no --cache was given");
    const std::vector<ice::proxy::StoreEntryInfo> entries = store.list();
    std::uint64_t total = 0;
    for (const auto& e : entries) total += e.bytes;
    if (*list) {
      std::cout << options.directory.string() << ": " << entries.size() << " entries, " << bytes_text(total) << '\n';
      for (const auto& e : entries)
        std::cout << "  " << std::left << std::setw(10) << e.kind << ' ' << e.key << "  " << std::right << std::setw(9)
                  << bytes_text(e.bytes) << "  " << age_text(e.last_used) << '\n';
    } else if (*size) {
      std::cout << options.directory.string() << ": " << entries.size() << " entries, " << bytes_text(total) << " of "
                << bytes_text(options.max_bytes) << '\n';
    } else if (*verify) {
      const auto damaged = store.verify(remove_damaged);
      for (const auto& [entry, what] : damaged)
        std::cout << "  damaged" << (remove_damaged ? " (removed): " : ": ") << what << '\n';
      const std::size_t checked = std::max(entries.size(), damaged.size());  // the store may change meanwhile
      std::cout << options.directory.string() << ": " << checked - damaged.size() << " of " << checked << " entries whole\n";
      if (!damaged.empty()) return static_cast<int>(app::kFailed);
    } else if (*clear) {
      const std::uint64_t freed = store.clear();
      std::cout << options.directory.string() << ": cleared " << entries.size() << " entries, " << bytes_text(freed) << '\n';
    }
    return static_cast<int>(app::kOk);
  });
}
