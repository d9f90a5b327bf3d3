#include "ice/proxy/store.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <utility>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <random>
#include <stdexcept>
#include <system_error>

#include <xxhash.h>

#include "ice/huge_pages.h"

namespace ice::proxy {

namespace fs = std::filesystem;

namespace {

constexpr char kMagic[8] = {'I', 'C', 'E', 'S', 'T', 'O', 'R', 'E'};
/// Bump when the layout of the file or of any entry kind changes: keys include it, and a file of
/// another version is rejected as damaged.
constexpr std::uint32_t kFormatVersion = 1;
constexpr std::size_t kHeaderBytes = 64;
constexpr std::size_t kKindBytes = 16;
constexpr const char* kSuffix = ".ice";
constexpr const char* kTempPrefix = ".tmp-";

enum : std::uint8_t { kInt32 = 1, kFloat64 = 2, kText = 3, kInt64 = 4 };

std::size_t element_bytes(std::uint8_t type) {
  switch (type) {
    case kInt32: return 4;
    case kFloat64: return 8;
    case kText: return 1;
    case kInt64: return 8;
    default: return 0;
  }
}

std::size_t padded(std::size_t bytes) { return (bytes + 7) & ~std::size_t{7}; }

struct Header {
  char magic[8];
  std::uint32_t version;
  std::uint32_t header_bytes;
  char kind[kKindBytes];
  std::uint64_t key_high, key_low;
  std::uint64_t payload_bytes;
  std::uint64_t checksum;
};
static_assert(sizeof(Header) == kHeaderBytes, "the entry header is 64 bytes");

struct RecordHead {
  std::uint32_t name_bytes;
  std::uint8_t type;
  std::uint8_t pad[3];
  std::uint64_t count;
};
static_assert(sizeof(RecordHead) == 16, "a record head is 16 bytes");

void require_kind(const std::string& kind) {
  if (kind.empty() || kind.size() >= kKindBytes ||
      !std::all_of(kind.begin(), kind.end(), [](char c) { return (c >= 'a' && c <= 'z') || c == '-'; }))
    throw std::invalid_argument("store: entry kind '" + kind + "' must be 1 to 15 of a-z and '-'");
}

std::string file_name(const std::string& kind, const StoreKey& key) { return kind + "-" + key.hex() + kSuffix; }

// "KIND-<32 hex>.ice" → (kind, key hex); nullopt for other files.
std::optional<std::pair<std::string, std::string>> parse_name(const std::string& name) {
  const std::size_t suffix = std::strlen(kSuffix);
  if (name.size() < 34 + suffix || name.compare(name.size() - suffix, suffix, kSuffix) != 0) return std::nullopt;
  const std::string stem = name.substr(0, name.size() - suffix);
  const std::string hex = stem.substr(stem.size() - 32);
  if (stem[stem.size() - 33] != '-' || !std::all_of(hex.begin(), hex.end(), [](char c) { return std::isxdigit(c); }))
    return std::nullopt;
  return std::make_pair(stem.substr(0, stem.size() - 33), hex);
}

StoreKey key_from_hex(const std::string& hex) {
  StoreKey key;
  key.high = std::stoull(hex.substr(0, 16), nullptr, 16);
  key.low = std::stoull(hex.substr(16, 16), nullptr, 16);
  return key;
}

class File {
 public:
  explicit File(int fd) : fd_(fd) {}
  File(const File&) = delete;
  ~File() {
    if (fd_ >= 0) ::close(fd_);
  }
  int get() const { return fd_; }
  int release() { return std::exchange(fd_, -1); }

 private:
  int fd_;
};

bool write_all(int fd, const void* data, std::size_t bytes) {
  const auto* p = static_cast<const char*>(data);
  while (bytes > 0) {
    const ssize_t n = ::write(fd, p, std::min<std::size_t>(bytes, std::size_t{1} << 30));
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    p += n;
    bytes -= static_cast<std::size_t>(n);
  }
  return true;
}

}  // namespace

// ---- options -----------------------------------------------------------------------------------

StoreOptions default_store_options() {
  StoreOptions options;
  if (const char* max_mb = std::getenv("ICE_CACHE_MAX_MB"); max_mb && *max_mb) {
    char* end = nullptr;
    const unsigned long long mb = std::strtoull(max_mb, &end, 10);
    if (!std::isdigit(static_cast<unsigned char>(max_mb[0])) || *end != '\0' || mb == 0 ||
        mb > (std::numeric_limits<std::uint64_t>::max() >> 20))
      throw std::invalid_argument(std::string("ICE_CACHE_MAX_MB='") + max_mb + "': expected a positive number of megabytes");
    options.max_bytes = static_cast<std::uint64_t>(mb) << 20;
  }
  if (const char* dir = std::getenv("ICE_CACHE")) {
    options.directory = dir;  // empty: off
  } else if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg) {
    options.directory = fs::path(xdg) / "ice";
  } else if (const char* home = std::getenv("HOME"); home && *home) {
    options.directory = fs::path(home) / ".cache" / "ice";
  }
  return options;
}

StoreOptions default_store_options(const fs::path& directory) {
  StoreOptions options = default_store_options();
  if (!directory.empty()) options.directory = directory;
  return options;
}

// ---- keys --------------------------------------------------------------------------------------

std::string StoreKey::hex() const {
  char text[33];
  std::snprintf(text, sizeof text, "%016llx%016llx", static_cast<unsigned long long>(high),
                static_cast<unsigned long long>(low));
  return text;
}

KeyHasher::KeyHasher(const std::string& kind) : state_(XXH3_createState()) {
  if (!state_) throw std::bad_alloc();
  XXH3_128bits_reset(static_cast<XXH3_state_t*>(state_));
  add(std::string(kMagic, sizeof kMagic)).add(static_cast<std::int64_t>(kFormatVersion)).add(kind);
}

KeyHasher::~KeyHasher() { XXH3_freeState(static_cast<XXH3_state_t*>(state_)); }

KeyHasher& KeyHasher::add_bytes(const void* data, std::size_t bytes) {
  const std::uint64_t size = bytes;
  XXH3_128bits_update(static_cast<XXH3_state_t*>(state_), &size, sizeof size);
  if (bytes > 0) XXH3_128bits_update(static_cast<XXH3_state_t*>(state_), data, bytes);
  return *this;
}

KeyHasher& KeyHasher::add_sparse(const Eigen::SparseMatrix<double>& m) {
  if (!m.isCompressed()) {
    Eigen::SparseMatrix<double> compressed = m;
    compressed.makeCompressed();
    return add_sparse(compressed);
  }
  add(static_cast<std::int64_t>(m.rows())).add(static_cast<std::int64_t>(m.cols())).add(static_cast<std::int64_t>(m.nonZeros()));
  add_bytes(m.outerIndexPtr(), sizeof(*m.outerIndexPtr()) * static_cast<std::size_t>(m.outerSize() + 1));
  add_bytes(m.innerIndexPtr(), sizeof(*m.innerIndexPtr()) * static_cast<std::size_t>(m.nonZeros()));
  return add_bytes(m.valuePtr(), sizeof(*m.valuePtr()) * static_cast<std::size_t>(m.nonZeros()));
}

KeyHasher& KeyHasher::add(const std::string& text) {
  const char tag = 's';
  XXH3_128bits_update(static_cast<XXH3_state_t*>(state_), &tag, 1);
  return add_bytes(text.data(), text.size());
}

KeyHasher& KeyHasher::add(double value) {
  const char tag = 'd';
  XXH3_128bits_update(static_cast<XXH3_state_t*>(state_), &tag, 1);
  if (value == 0) value = 0;  // -0 and +0 mean the same option
  return add_bytes(&value, sizeof value);
}

KeyHasher& KeyHasher::add(std::int64_t value) {
  const char tag = 'i';
  XXH3_128bits_update(static_cast<XXH3_state_t*>(state_), &tag, 1);
  return add_bytes(&value, sizeof value);
}

KeyHasher& KeyHasher::add(const StoreKey& key) {
  const std::uint64_t words[2] = {key.high, key.low};
  const char tag = 'k';
  XXH3_128bits_update(static_cast<XXH3_state_t*>(state_), &tag, 1);
  return add_bytes(words, sizeof words);
}

StoreKey KeyHasher::finish() const {
  const XXH128_hash_t h = XXH3_128bits_digest(static_cast<XXH3_state_t*>(state_));
  return {h.high64, h.low64};
}

// ---- writing -----------------------------------------------------------------------------------

void EntryWriter::put(const std::string& name, const std::int32_t* data, std::size_t count) {
  records_.push_back({name, kInt32, data, count});
}
void EntryWriter::put(const std::string& name, const double* data, std::size_t count) {
  records_.push_back({name, kFloat64, data, count});
}
void EntryWriter::put_text(const std::string& name, std::string text) {
  owned_text_.push_back(std::move(text));
  records_.push_back({name, kText, owned_text_.back().data(), owned_text_.back().size()});
}
void EntryWriter::put_int(const std::string& name, std::int64_t value) {
  owned_ints_.push_back(value);
  records_.push_back({name, kInt64, &owned_ints_.back(), 1});
}
void EntryWriter::put_sparse(const std::string& name, const Eigen::SparseMatrix<double>& m) {
  if (!m.isCompressed()) throw std::invalid_argument("EntryWriter::put_sparse: '" + name + "' is not compressed");
  put_int(name + ".rows", m.rows());
  put_int(name + ".cols", m.cols());
  put(name + ".outer", m.outerIndexPtr(), static_cast<std::size_t>(m.outerSize()) + 1);
  put(name + ".inner", m.innerIndexPtr(), static_cast<std::size_t>(m.nonZeros()));
  put(name + ".values", m.valuePtr(), static_cast<std::size_t>(m.nonZeros()));
}

// ---- reading -----------------------------------------------------------------------------------

namespace {
// Copies an array out of the mapped entry into a fresh buffer. Large buffers are offered huge pages
// first: copying into fresh memory is otherwise mostly page faults (a hierarchy's tens of MB). That
// helps Eigen's buffers, which are not initialised; a std::vector's were zero-filled (touched) already.
void copy_out(void* to, const void* from, std::size_t bytes) {
  if (bytes == 0) return;
  if (bytes >= (std::size_t{1} << 22)) advise_huge_pages(to, bytes);
  std::memcpy(to, from, bytes);
}
}  // namespace

EntryReader::EntryReader(EntryReader&& other) noexcept
    : path_(std::move(other.path_)), map_(other.map_), map_bytes_(other.map_bytes_), arrays_(std::move(other.arrays_)) {
  other.map_ = nullptr;
  other.map_bytes_ = 0;
}

EntryReader::~EntryReader() {
  if (map_) ::munmap(map_, map_bytes_);
}

const EntryReader::Array& EntryReader::find(const std::string& name, std::uint8_t type) const {
  for (const Array& a : arrays_)
    if (a.name == name) {
      if (a.type != type) throw std::runtime_error(path_.string() + ": array '" + name + "' has the wrong type");
      return a;
    }
  throw std::runtime_error(path_.string() + ": no array '" + name + "'");
}

std::vector<std::int32_t> EntryReader::ints(const std::string& name) const {
  const Array& a = find(name, kInt32);
  std::vector<std::int32_t> out(a.count);
  copy_out(out.data(), a.data, a.count * 4);
  return out;
}

std::vector<double> EntryReader::doubles(const std::string& name) const {
  const Array& a = find(name, kFloat64);
  std::vector<double> out(a.count);
  copy_out(out.data(), a.data, a.count * 8);
  return out;
}

std::string EntryReader::text(const std::string& name) const {
  const Array& a = find(name, kText);
  return std::string(reinterpret_cast<const char*>(a.data), a.count);
}

bool EntryReader::has(const std::string& name) const {
  return std::any_of(arrays_.begin(), arrays_.end(), [&name](const Array& a) { return a.name == name; });
}

std::int64_t EntryReader::integer(const std::string& name) const {
  const Array& a = find(name, kInt64);
  if (a.count != 1) throw std::runtime_error(path_.string() + ": '" + name + "' is not one integer");
  std::int64_t v = 0;
  std::memcpy(&v, a.data, 8);
  return v;
}

namespace {
std::pair<Eigen::Index, Eigen::Index> shape_of(const EntryReader& r, const std::string& name, std::uint64_t count) {
  const std::int64_t rows = r.integer(name + ".rows"), cols = r.integer(name + ".cols");
  if (rows < 0 || cols < 0 || (cols != 0 && static_cast<std::uint64_t>(rows) > count / static_cast<std::uint64_t>(cols)) ||
      static_cast<std::uint64_t>(rows) * static_cast<std::uint64_t>(cols) != count)
    throw std::runtime_error(r.path().string() + ": '" + name + "' has a shape that does not fit its data");
  return {rows, cols};
}
}  // namespace

Eigen::MatrixXi EntryReader::int_matrix(const std::string& name, std::int64_t min_entry, std::int64_t max_entry) const {
  const Array& a = find(name, kInt32);
  const auto [rows, cols] = shape_of(*this, name, a.count);
  Eigen::MatrixXi m(rows, cols);
  copy_out(m.data(), a.data, a.count * 4);
  if (m.size() > 0 && (m.minCoeff() < min_entry || m.maxCoeff() > max_entry))
    throw std::runtime_error(path_.string() + ": '" + name + "' has entries out of range");
  return m;
}

Eigen::MatrixXd EntryReader::double_matrix(const std::string& name) const {
  const Array& a = find(name, kFloat64);
  const auto [rows, cols] = shape_of(*this, name, a.count);
  Eigen::MatrixXd m(rows, cols);
  copy_out(m.data(), a.data, a.count * 8);
  if (!m.allFinite()) throw std::runtime_error(path_.string() + ": '" + name + "' has a value that is not finite");
  return m;
}

Eigen::SparseMatrix<double> EntryReader::sparse(const std::string& name) const {
  const std::int64_t rows = integer(name + ".rows"), cols = integer(name + ".cols");
  const Array& outer = find(name + ".outer", kInt32);
  const Array& inner = find(name + ".inner", kInt32);
  const Array& values = find(name + ".values", kFloat64);
  const auto bad = [&](const std::string& what) {
    return std::runtime_error(path_.string() + ": sparse matrix '" + name + "': " + what);
  };
  if (rows < 0 || cols < 0 || rows > INT32_MAX || cols > INT32_MAX || outer.count != static_cast<std::uint64_t>(cols) + 1 ||
      inner.count != values.count)
    throw bad("shape and arrays disagree");
  const auto* o = reinterpret_cast<const std::int32_t*>(outer.data);
  const auto* in = reinterpret_cast<const std::int32_t*>(inner.data);
  const auto* v = reinterpret_cast<const double*>(values.data);
  if (o[0] != 0 || o[cols] < 0 || static_cast<std::uint64_t>(o[cols]) != inner.count)
    throw bad("column pointers do not span the entries");
  for (std::int64_t j = 0; j < cols; ++j)  // every pointer in range before any entry is read
    if (o[j + 1] < o[j] || o[j + 1] > o[cols]) throw bad("column pointers decrease or run past the entries");
  for (std::int64_t j = 0; j < cols; ++j) {
    for (std::int32_t k = o[j]; k < o[j + 1]; ++k)
      if (in[k] < 0 || in[k] >= rows || (k > o[j] && in[k] <= in[k - 1]) || !std::isfinite(v[k]))
        throw bad("column " + std::to_string(j) + " has a row index out of range or out of order, or a value not finite");
  }
  Eigen::SparseMatrix<double> m(rows, cols);
  m.resizeNonZeros(static_cast<Eigen::Index>(inner.count));
  copy_out(m.outerIndexPtr(), o, outer.count * 4);
  copy_out(m.innerIndexPtr(), in, inner.count * 4);
  copy_out(m.valuePtr(), v, values.count * 8);
  return m;
}

// ---- the store ---------------------------------------------------------------------------------

Store::Store(StoreOptions options) : options_(std::move(options)) {}

fs::path Store::entry_path(const std::string& kind, const StoreKey& key) const {
  require_kind(kind);
  return options_.directory / file_name(kind, key);
}

namespace {

// The file could not be read just now (permissions, descriptors, memory): not evidence that the
// entry is damaged, so it is left in place.
struct Unreadable : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Which file a path named when it was checked: a damaged entry is removed only if the path still
// names that file (another process may have renamed a fresh entry into place since).
struct FileIdentity {
  dev_t device = 0;
  ino_t inode = 0;
};

// Maps and checks the file at `path` as entry `kind`/`key`. Throws Unreadable when it cannot be
// read now, std::runtime_error describing the damage otherwise; returns false when there is no
// such file.
bool map_entry(const fs::path& path, const std::string& kind, const StoreKey* key, void*& map, std::size_t& bytes,
               FileIdentity* identity = nullptr, StoreKey* found = nullptr) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    const int error = errno;
    if (error == ENOENT) return false;
    throw Unreadable(path.string() + ": cannot be opened (" + std::strerror(error) + ")");
  }
  const File file(fd);
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const int error = errno;
    throw Unreadable(path.string() + ": cannot be read (" + std::strerror(error) + ")");
  }
  if (identity) *identity = {st.st_dev, st.st_ino};
  bytes = static_cast<std::size_t>(st.st_size);
  if (bytes < kHeaderBytes) throw std::runtime_error(path.string() + ": truncated (" + std::to_string(bytes) + " bytes)");
  // Populated at once: the whole payload is read (checksum, copies), and page by page faults cost more.
  map = ::mmap(nullptr, bytes, PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
  if (map == MAP_FAILED) {
    const int error = errno;
    map = nullptr;
    throw Unreadable(path.string() + ": cannot be mapped (" + std::strerror(error) + ")");
  }
  Header h{};
  std::memcpy(&h, map, sizeof h);
  const auto fail = [&](const std::string& what) {
    ::munmap(map, bytes);
    map = nullptr;
    return std::runtime_error(path.string() + ": " + what);
  };
  if (std::memcmp(h.magic, kMagic, sizeof kMagic) != 0) throw fail("not an ICE store entry");
  if (h.version != kFormatVersion)
    throw fail("format version " + std::to_string(h.version) + ", this build reads " + std::to_string(kFormatVersion));
  if (h.header_bytes != kHeaderBytes) throw fail("header of an unknown size");
  char kind_text[kKindBytes + 1] = {};
  std::memcpy(kind_text, h.kind, kKindBytes);
  if (kind != kind_text) throw fail(std::string("an entry of kind '") + kind_text + "', not '" + kind + "'");
  if (key && (h.key_high != key->high || h.key_low != key->low))
    throw fail("an entry of another key (another mesh or other options)");
  if (found) *found = StoreKey{h.key_high, h.key_low};
  if (h.payload_bytes != bytes - kHeaderBytes)
    throw fail("truncated or extended: " + std::to_string(bytes - kHeaderBytes) + " payload bytes, the header says " +
               std::to_string(h.payload_bytes));
  const auto* payload = static_cast<const unsigned char*>(map) + kHeaderBytes;
  if (XXH3_64bits(payload, h.payload_bytes) != h.checksum) throw fail("checksum mismatch (the payload was changed)");
  return true;
}

// Removes the damaged entry at `path` if it is still the file that was checked.
void remove_if_same(const fs::path& path, const FileIdentity& checked) {
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && st.st_dev == checked.device && st.st_ino == checked.inode) {
    std::error_code ec;
    fs::remove(path, ec);
  }
}

}  // namespace

void EntryReader::parse() {
  const auto* p = static_cast<const unsigned char*>(map_) + kHeaderBytes;
  const auto* end = static_cast<const unsigned char*>(map_) + map_bytes_;
  const fs::path& path = path_;
  arrays_.clear();
  while (p < end) {
    RecordHead r{};
    if (static_cast<std::size_t>(end - p) < sizeof r) throw std::runtime_error(path.string() + ": a record is cut off");
    std::memcpy(&r, p, sizeof r);
    p += sizeof r;
    const std::size_t elem = element_bytes(r.type);
    if (elem == 0 || r.name_bytes == 0 || r.name_bytes > 256 || r.count > (std::uint64_t{1} << 40))
      throw std::runtime_error(path.string() + ": a record head is malformed");
    const std::size_t name_span = padded(r.name_bytes), data_span = padded(r.count * elem);
    if (static_cast<std::size_t>(end - p) < name_span + data_span)
      throw std::runtime_error(path.string() + ": a record runs past the end");
    EntryReader::Array a;
    a.name.assign(reinterpret_cast<const char*>(p), r.name_bytes);
    a.type = r.type;
    a.count = r.count;
    a.data = p + name_span;
    arrays_.push_back(std::move(a));
    p += name_span + data_span;
  }
}

std::optional<EntryReader> Store::load(const std::string& kind, const StoreKey& key, std::string* damage) const {
  if (!enabled()) return std::nullopt;
  const fs::path path = entry_path(kind, key);
  EntryReader reader;
  reader.path_ = path;
  FileIdentity identity;
  try {
    if (!map_entry(path, kind, &key, reader.map_, reader.map_bytes_, &identity)) return std::nullopt;
    reader.parse();
  } catch (const Unreadable&) {
    return std::nullopt;  // left in place: a miss now, perhaps a hit later
  } catch (const std::runtime_error& e) {
    if (damage) *damage = e.what();
    remove_if_same(path, identity);
    return std::nullopt;
  }
  std::error_code ec;
  fs::last_write_time(path, fs::file_time_type::clock::now(), ec);  // least recently used: this one was used
  return std::optional<EntryReader>(std::move(reader));
}

void Store::discard(const std::string& kind, const StoreKey& key) const {
  if (!enabled()) return;
  std::error_code ec;
  fs::remove(entry_path(kind, key), ec);
}

namespace {

// Writes `entry` to a temporary file beside `path` and renames it over `path` (atomic on POSIX file
// systems: a reader sees the old file or the whole new one). On failure returns false, leaves no
// temporary file behind and says why in `error`.
bool write_entry(const fs::path& path, const std::string& kind, const StoreKey& key, const EntryWriter& entry,
                 std::string* error) {
  const auto fail = [&](const std::string& what) {
    if (error) *error = what;
    return false;
  };
  std::error_code ec;
  static std::atomic<unsigned> counter{0};
  std::random_device random;
  const fs::path temp = path.parent_path() / (kTempPrefix + path.filename().string() + "." + std::to_string(::getpid()) +
                                              "." + std::to_string(counter++) + "." + std::to_string(random()));
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) return fail(temp.string() + ": cannot be created (" + std::strerror(errno) + ")");
  bool ok = true;
  {
    File file(fd);
    Header h{};
    std::memcpy(h.magic, kMagic, sizeof kMagic);
    h.version = kFormatVersion;
    h.header_bytes = kHeaderBytes;
    std::memcpy(h.kind, kind.data(), kind.size());
    h.key_high = key.high;
    h.key_low = key.low;
    XXH3_state_t* state = XXH3_createState();
    if (!state) {
      fs::remove(temp, ec);
      return fail("out of memory for the checksum state");
    }
    XXH3_64bits_reset(state);
    int error_number = 0;  // errno of the first failed call
    ok = write_all(fd, &h, sizeof h);
    if (!ok) error_number = errno;
    static const char zeros[8] = {};
    const auto emit = [&](const void* data, std::size_t bytes) {
      if (!ok) return;
      XXH3_64bits_update(state, data, bytes);
      h.payload_bytes += bytes;
      ok = write_all(fd, data, bytes);
      if (!ok) error_number = errno;
    };
    for (const EntryWriter::Record& r : entry.records()) {
      RecordHead head{};
      head.name_bytes = static_cast<std::uint32_t>(r.name.size());
      head.type = r.type;
      head.count = r.count;
      emit(&head, sizeof head);
      emit(r.name.data(), r.name.size());
      emit(zeros, padded(r.name.size()) - r.name.size());
      const std::size_t bytes = r.count * element_bytes(r.type);
      if (bytes) emit(r.data, bytes);
      emit(zeros, padded(bytes) - bytes);
    }
    h.checksum = XXH3_64bits_digest(state);
    XXH3_freeState(state);
    if (ok && !(ok = ::pwrite(fd, &h, sizeof h, 0) == static_cast<ssize_t>(sizeof h))) error_number = errno ? errno : EIO;
    if (ok && !(ok = ::close(file.release()) == 0)) error_number = errno;  // reports a deferred write error
    if (!ok) {
      const std::string why = std::strerror(error_number);
      fs::remove(temp, ec);
      return fail(temp.string() + ": cannot be written (" + why + ")");
    }
  }
  fs::rename(temp, path, ec);
  if (ec) {
    fs::remove(temp, ec);
    return fail(path.string() + ": cannot be renamed into place (" + ec.message() + ")");
  }
  return true;
}

}  // namespace

bool Store::save(const std::string& kind, const StoreKey& key, const EntryWriter& entry, std::string* error) const {
  if (!enabled()) return false;
  const fs::path path = entry_path(kind, key);
  std::error_code ec;
  fs::create_directories(options_.directory, ec);
  if (ec) {
    if (error) *error = options_.directory.string() + ": cannot be created (" + ec.message() + ")";
    return false;
  }
  if (!write_entry(path, kind, key, entry, error)) return false;
  evict(options_.max_bytes, path);
  return true;
}

void write_entry_file(const fs::path& path, const std::string& kind, const StoreKey& key, const EntryWriter& entry) {
  require_kind(kind);
  std::string error;
  if (!write_entry(path, kind, key, entry, &error)) throw std::runtime_error(error);
}

EntryReader read_entry_file(const fs::path& path, const std::string& kind, StoreKey& key) {
  require_kind(kind);
  EntryReader reader;
  reader.path_ = path;
  if (!map_entry(path, kind, nullptr, reader.map_, reader.map_bytes_, nullptr, &key))
    throw std::runtime_error(path.string() + ": no such file");
  reader.parse();
  return reader;
}

std::vector<StoreEntryInfo> Store::list() const {
  std::vector<StoreEntryInfo> entries;
  std::error_code ec;
  if (!enabled() || !fs::is_directory(options_.directory, ec)) return entries;
  for (const fs::directory_entry& e : fs::directory_iterator(options_.directory, ec)) {
    const auto parsed = parse_name(e.path().filename().string());
    if (!parsed || !e.is_regular_file(ec)) continue;
    StoreEntryInfo info;
    info.path = e.path();
    info.kind = parsed->first;
    info.key = parsed->second;
    info.bytes = e.file_size(ec);
    info.last_used = e.last_write_time(ec);
    if (!ec) entries.push_back(std::move(info));
  }
  std::sort(entries.begin(), entries.end(),
            [](const StoreEntryInfo& a, const StoreEntryInfo& b) { return a.last_used > b.last_used; });
  return entries;
}

std::vector<std::pair<StoreEntryInfo, std::string>> Store::verify(bool remove_damaged) const {
  std::vector<std::pair<StoreEntryInfo, std::string>> damaged;
  for (const StoreEntryInfo& info : list()) {
    EntryReader reader;
    reader.path_ = info.path;
    FileIdentity identity;
    try {
      require_kind(info.kind);
      const StoreKey key = key_from_hex(info.key);
      if (map_entry(info.path, info.kind, &key, reader.map_, reader.map_bytes_, &identity)) reader.parse();
    } catch (const Unreadable& e) {
      damaged.emplace_back(info, std::string(e.what()) + " (left in place)");
    } catch (const std::exception& e) {
      damaged.emplace_back(info, e.what());
      if (remove_damaged) remove_if_same(info.path, identity);
    }
  }
  return damaged;
}

std::uint64_t Store::evict(std::uint64_t max_bytes, const fs::path& keep) const {
  std::uint64_t total = 0, freed = 0;
  // Temporary files of writers that died before renaming (a killed process): removed after an hour
  // (no save takes that long), counted until then.
  std::error_code ec;
  if (enabled() && fs::is_directory(options_.directory, ec))
    for (const fs::directory_entry& e : fs::directory_iterator(options_.directory, ec)) {
      const std::string name = e.path().filename().string();
      if (name.rfind(kTempPrefix, 0) != 0 || name.find(kSuffix) == std::string::npos) continue;
      std::error_code ec_file;
      const std::uintmax_t bytes = e.file_size(ec_file);
      const auto age = fs::file_time_type::clock::now() - e.last_write_time(ec_file);
      if (ec_file) continue;
      if (age > std::chrono::hours(1) && fs::remove(e.path(), ec_file)) freed += bytes;
      else total += bytes;
    }
  std::vector<StoreEntryInfo> entries = list();
  for (const StoreEntryInfo& e : entries) total += e.bytes;
  for (auto it = entries.rbegin(); it != entries.rend() && total > max_bytes; ++it) {
    if (it->path == keep) continue;
    std::error_code ec;
    if (fs::remove(it->path, ec)) {
      total -= it->bytes;
      freed += it->bytes;
    }
  }
  return freed;
}

std::uint64_t Store::clear() const {
  std::uint64_t freed = 0;
  std::error_code ec;
  if (!enabled() || !fs::is_directory(options_.directory, ec)) return 0;
  std::vector<fs::path> doomed;
  for (const fs::directory_entry& e : fs::directory_iterator(options_.directory, ec)) {
    const std::string name = e.path().filename().string();
    if (parse_name(name) || (name.rfind(kTempPrefix, 0) == 0 && name.find(kSuffix) != std::string::npos))
      doomed.push_back(e.path());
  }
  for (const fs::path& p : doomed) {
    const std::uintmax_t bytes = fs::file_size(p, ec);
    if (fs::remove(p, ec)) freed += ec ? 0 : bytes;
  }
  return freed;
}

}  // namespace ice::proxy
