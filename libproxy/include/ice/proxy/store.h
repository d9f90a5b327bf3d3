#pragma once
/// \file store.h
/// A persistent, content-addressed store of what the recipes set up once: coarse spaces and coarse
/// proxies, so that a second run on the same mesh with the same options loads them instead of
/// coarsening and assembling again.
///
/// An entry is one binary file `KIND-KEY.ice` in the store's directory: a 64-byte header (magic,
/// format version, kind, the 128-bit key, payload size and checksum) and named arrays. The key is an
/// XXH3-128 hash of the input's arrays, every option that changes the result and the format version,
/// so another mesh, other options or another version never find the entry. Loading maps the file,
/// checks the header, the key and the payload's XXH3-64 checksum, then the arrays' structure (shapes,
/// index ranges, sorted sparse columns) and what the consumer checks itself (a restored
/// fem::CoarseProxy checks that P's rows sum to 1): an entry failing any check is reported, removed
/// and rebuilt, never used.
///
/// Writers write a temporary file in the directory and rename it over the entry's name (atomic on
/// POSIX file systems), so a reader never sees half an entry and several processes may fill the
/// same entry at once (the last rename wins; the contents are identical). After each write the
/// store evicts the least recently used entries (by modification time, which a hit refreshes) until
/// it holds at most StoreOptions::max_bytes.
#include <cstdint>
#include <deque>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/SparseCore>

namespace ice::proxy {

/// Where a recipe's setup came from.
enum class CacheStatus {
  off,      ///< no store was used
  miss,     ///< no entry: built, then saved
  hit,      ///< loaded from the store
  rebuilt,  ///< an entry was damaged (reported, removed): built again and saved
};

/// The store's size bound when none is given: 4 GiB.
constexpr std::uint64_t kDefaultStoreBytes = std::uint64_t{4} << 30;

struct StoreOptions {
  std::filesystem::path directory;  ///< empty: no store
  std::uint64_t max_bytes = kDefaultStoreBytes;
};

/// The default store: $ICE_CACHE if set (an empty value turns the store off), else
/// $XDG_CACHE_HOME/ice, else $HOME/.cache/ice; no store without any of them. The size bound is
/// $ICE_CACHE_MAX_MB megabytes when set (a positive integer), else kDefaultStoreBytes.
/// Throws std::invalid_argument on a malformed $ICE_CACHE_MAX_MB.
StoreOptions default_store_options();
/// The same in `directory` instead when it is not empty (a --cache or cache= argument).
StoreOptions default_store_options(const std::filesystem::path& directory);

/// A 128-bit content key.
struct StoreKey {
  std::uint64_t high = 0, low = 0;
  std::string hex() const;  ///< 32 lowercase hex digits
  bool operator==(const StoreKey& other) const { return high == other.high && low == other.low; }
};

/// Builds a StoreKey from everything that decides an entry's contents. Each add() hashes a type tag
/// and the size with the bytes, so ("ab", "c") and ("a", "bc") differ.
class KeyHasher {
 public:
  explicit KeyHasher(const std::string& kind);
  KeyHasher(const KeyHasher&) = delete;
  KeyHasher& operator=(const KeyHasher&) = delete;
  ~KeyHasher();
  KeyHasher& add_bytes(const void* data, std::size_t bytes);
  KeyHasher& add(const std::string& text);
  KeyHasher& add(const char* text) { return add(std::string(text)); }
  KeyHasher& add(double value);
  KeyHasher& add(std::int64_t value);
  KeyHasher& add(int value) { return add(static_cast<std::int64_t>(value)); }
  KeyHasher& add(bool value) { return add(static_cast<std::int64_t>(value)); }
  KeyHasher& add(const StoreKey& key);
  template <class Derived>
  KeyHasher& add_matrix(const Eigen::PlainObjectBase<Derived>& m) {
    add(static_cast<std::int64_t>(m.rows())).add(static_cast<std::int64_t>(m.cols()));
    return add_bytes(m.data(), sizeof(typename Derived::Scalar) * static_cast<std::size_t>(m.size()));
  }
  /// The matrix's shape and its compressed arrays (an uncompressed one is hashed as compressed).
  KeyHasher& add_sparse(const Eigen::SparseMatrix<double>& m);
  StoreKey finish() const;

 private:
  void* state_;
};

/// The named arrays of one entry, to be written. Arrays given by pointer are not copied: they must
/// stay alive until Store::save returns.
class EntryWriter {
 public:
  EntryWriter() = default;
  // Records point into the writer's own texts and integers: a copy would point into the original's.
  EntryWriter(const EntryWriter&) = delete;
  EntryWriter& operator=(const EntryWriter&) = delete;
  EntryWriter(EntryWriter&&) = default;  // (a moved deque keeps its elements where they are)
  EntryWriter& operator=(EntryWriter&&) = default;
  void put(const std::string& name, const std::int32_t* data, std::size_t count);
  void put(const std::string& name, const double* data, std::size_t count);
  void put_text(const std::string& name, std::string text);  ///< copied
  void put_int(const std::string& name, std::int64_t value);  ///< copied
  void put_sparse(const std::string& name, const Eigen::SparseMatrix<double>& m);  ///< compressed; not copied
  template <class Derived>
  void put_matrix(const std::string& name, const Eigen::PlainObjectBase<Derived>& m) {
    put_int(name + ".rows", m.rows());
    put_int(name + ".cols", m.cols());
    put(name, m.data(), static_cast<std::size_t>(m.size()));
  }

  struct Record {
    std::string name;
    std::uint8_t type = 0;
    const void* data = nullptr;
    std::uint64_t count = 0;
  };
  const std::vector<Record>& records() const { return records_; }

 private:
  std::vector<Record> records_;
  std::deque<std::string> owned_text_;
  std::deque<std::int64_t> owned_ints_;
};

/// A loaded entry: its file mapped into memory, checked (header, key, checksum) and parsed. The
/// getters check each array's type and size and throw std::runtime_error naming the entry and the
/// array otherwise (the store then treats the entry as damaged).
class EntryReader {
 public:
  EntryReader(EntryReader&&) noexcept;
  EntryReader& operator=(EntryReader&&) = delete;
  ~EntryReader();
  std::vector<std::int32_t> ints(const std::string& name) const;
  std::vector<double> doubles(const std::string& name) const;
  std::string text(const std::string& name) const;
  std::int64_t integer(const std::string& name) const;
  /// Whether the entry has an array of that name (an optional part, absent from older entries).
  bool has(const std::string& name) const;
  /// A matrix put with put_matrix; entries of an int matrix must lie in [min_entry, max_entry].
  Eigen::MatrixXi int_matrix(const std::string& name, std::int64_t min_entry, std::int64_t max_entry) const;
  Eigen::MatrixXd double_matrix(const std::string& name) const;
  /// A sparse matrix put with put_sparse: its column pointers, row indices (strictly increasing in
  /// each column, in range) and finite values checked.
  Eigen::SparseMatrix<double> sparse(const std::string& name) const;
  const std::filesystem::path& path() const { return path_; }

 private:
  friend class Store;
  friend EntryReader read_entry_file(const std::filesystem::path&, const std::string&, StoreKey&);
  EntryReader() = default;
  struct Array {
    std::string name;
    std::uint8_t type = 0;
    const unsigned char* data = nullptr;
    std::uint64_t count = 0;
  };
  const Array& find(const std::string& name, std::uint8_t type) const;
  /// Splits the mapped payload into its arrays; throws std::runtime_error on a malformed record.
  void parse();
  std::filesystem::path path_;
  void* map_ = nullptr;
  std::size_t map_bytes_ = 0;
  std::vector<Array> arrays_;
};

/// An entry in a file of the caller's choosing rather than in a store (an explicit save of a setup
/// or a hierarchy), in the same format. Written to a temporary file beside `path`, then renamed over
/// it: an existing file at `path` is replaced (callers check first: ice::require_writable). Throws
/// std::runtime_error naming the file when it cannot be written, leaving no partial file behind.
void write_entry_file(const std::filesystem::path& path, const std::string& kind, const StoreKey& key,
                      const EntryWriter& entry);
/// The entry file at `path`, mapped and checked as the store checks its entries (magic, format
/// version, kind, size, checksum, records); its key, which the caller compares, in `key`. Throws
/// std::runtime_error naming the file and the defect, also when there is no such file or it
/// cannot be read.
EntryReader read_entry_file(const std::filesystem::path& path, const std::string& kind, StoreKey& key);

/// One entry as the store lists it.
struct StoreEntryInfo {
  std::filesystem::path path;
  std::string kind, key;
  std::uint64_t bytes = 0;
  std::filesystem::file_time_type last_used;
};

class Store {
 public:
  /// A store in options.directory (created on the first save). A default-constructed or
  /// empty-directory store is off: loads miss and saves do nothing.
  Store() = default;
  explicit Store(StoreOptions options);
  bool enabled() const { return !options_.directory.empty(); }
  const StoreOptions& options() const { return options_; }
  std::filesystem::path entry_path(const std::string& kind, const StoreKey& key) const;

  /// The entry, checked; std::nullopt when there is none. A damaged entry (truncated, another
  /// format version, another key, a checksum that does not match, records that do not parse) is
  /// removed (unless another process has renamed a new entry into its place meanwhile) and
  /// described in `damage`, and std::nullopt returned; an entry that cannot be read now (no
  /// permission, no memory) is left in place and std::nullopt returned. A hit refreshes the entry's
  /// modification time (least recently used eviction).
  std::optional<EntryReader> load(const std::string& kind, const StoreKey& key, std::string* damage = nullptr) const;
  /// Removes the entry `kind`/`key` after a consumer found its contents inconsistent.
  void discard(const std::string& kind, const StoreKey& key) const;
  /// Writes the entry atomically, then evicts down to the size bound (the new entry is kept even
  /// when it alone exceeds it). Returns false, leaving the store as it was, when the directory or
  /// the file cannot be written (a full disk, no permission): a store is an accelerator, not a need.
  bool save(const std::string& kind, const StoreKey& key, const EntryWriter& entry, std::string* error = nullptr) const;

  /// The entries, most recently used first (temporary files of writers are not entries).
  std::vector<StoreEntryInfo> list() const;
  /// Reads and checks every entry (header, key, checksum, record structure); returns the damaged
  /// ones with what is wrong and removes them when `remove_damaged` (an entry that cannot be read
  /// now, for want of permission or memory, is reported and left in place).
  std::vector<std::pair<StoreEntryInfo, std::string>> verify(bool remove_damaged) const;
  /// Removes least recently used entries until at most max_bytes remain (counting the temporary
  /// files of writers, which are removed once an hour old); returns the bytes freed. `keep` (an
  /// entry's path) is never removed.
  std::uint64_t evict(std::uint64_t max_bytes, const std::filesystem::path& keep = {}) const;
  /// Removes every entry and leftover temporary file; returns the bytes freed.
  std::uint64_t clear() const;

 private:
  StoreOptions options_;
};

/// Where a recipe's setup came from and what the store cost.
struct CacheReport {
  CacheStatus status = CacheStatus::off;
  double load_seconds = 0;  ///< mapping, checking and copying the entries out (hit), or the failed load
  double save_seconds = 0;  ///< writing the entries (miss, rebuilt)
  std::string damage;       ///< what was wrong with a damaged entry (rebuilt)
  std::string save_error;   ///< why an entry could not be written (the run went on without it)
  std::vector<std::string> keys;  ///< the entries used or written
};

}  // namespace ice::proxy
