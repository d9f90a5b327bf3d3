#pragma once
// What the readers and writers of store entries and entry files share (stored_setup.cpp, multigrid.cpp).
#include <chrono>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

#include "ice/mesh.h"
#include "ice/proxy/store.h"
#include "ice/wall_time.h"

namespace ice::proxy::detail {

/// Throws std::runtime_error "path: what": the store then treats the entry as damaged.
[[noreturn]] inline void fail(const std::string& path, const std::string& what) { throw std::runtime_error(path + ": " + what); }
/// fail(path, what) unless `ok`. The message is a plain string because checks run once per stored
/// element: a composed message would be built on every call (fail() composes only on failure).
inline void require(bool ok, const std::string& path, const char* what) {
  if (!ok) fail(path, what);
}

/// The key of an explicitly saved file of `kind` for `mesh`: the mesh's arrays alone (what the file
/// holds it says itself), so a file made for another mesh, or a store's entry, has another key.
inline StoreKey file_key(const std::string& kind, const TriangleMesh& mesh) {
  KeyHasher h(kind);
  h.add("file").add_matrix(mesh.V).add_matrix(mesh.F);
  return h.finish();
}

/// The entry file at `path` of `kind`, checked (read_entry_file) and saved for `mesh`; throws
/// std::runtime_error naming the file otherwise.
inline EntryReader read_file_for(const std::filesystem::path& path, const std::string& kind, const TriangleMesh& mesh) {
  StoreKey key;
  EntryReader entry = read_entry_file(path, kind, key);
  if (!(key == file_key(kind, mesh)))
    throw std::runtime_error(path.string() + ": a " + kind + " made for another mesh (other positions or faces), or an entry of a "
                             "store (which only the store reads: its key holds the options too)");
  return entry;
}

/// Writes `entry` as `kind`/`key` and records it in `cache`: the key, the time since `start` (when the
/// writer began collecting the arrays), status miss unless already rebuilt, and any error (the run
/// goes on without the entry).
inline void save_entry(const Store& store, const std::string& kind, const StoreKey& key, const EntryWriter& entry,
                       CacheReport& cache, std::chrono::steady_clock::time_point start) {
  std::string error;
  if (!store.save(kind, key, entry, &error)) cache.save_error = error;
  if (cache.status == CacheStatus::off) cache.status = CacheStatus::miss;
  cache.save_seconds = seconds_since(start);
  cache.keys.push_back(key.hex());
}

/// A value loaded from the store with the report of its load: what load_entry returns when the value
/// itself has no `cache`.
template <class T>
struct Stored {
  T value;
  CacheReport cache;
};

/// The entry `kind`/`key` read by `parse(entry, path)` into a T (a value with a CacheReport `cache`),
/// or std::nullopt: a miss, or a damaged entry — one the store rejects, or whose contents `parse`
/// finds inconsistent (any exception), which is then removed. `cache` says which (miss, rebuilt with
/// the damage) and what the attempt cost; on a hit the value's own `cache` says hit, its time and key.
template <class T, class Parse>
std::optional<T> load_entry(const Store& store, const std::string& kind, const StoreKey& key, CacheReport& cache,
                            Parse&& parse) {
  const auto start = std::chrono::steady_clock::now();
  const auto failed = [&](CacheStatus status, std::string damage) -> std::optional<T> {
    cache.status = status;
    cache.damage = std::move(damage);
    cache.load_seconds = seconds_since(start);
    return std::nullopt;
  };
  std::string damage;
  std::optional<EntryReader> entry = store.load(kind, key, &damage);
  if (!entry) {
    const CacheStatus status = damage.empty() ? CacheStatus::miss : CacheStatus::rebuilt;
    return failed(status, std::move(damage));
  }
  std::optional<T> value;
  try {
    value.emplace(parse(*entry, entry->path().string()));
  } catch (const std::exception& e) {  // runtime_error from the entry's getters, others from the consumer's checks
    store.discard(kind, key);
    return failed(CacheStatus::rebuilt, e.what());
  }
  value->cache.status = CacheStatus::hit;
  value->cache.load_seconds = seconds_since(start);
  value->cache.keys.push_back(key.hex());
  return value;
}

}  // namespace ice::proxy::detail
