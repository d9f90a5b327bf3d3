#include "ice/mesh_io.h"
#include "ice/point_cloud.h"

#include "file_extension.h"
#include "run_tasks.h"
#include "soup_duplicates.h"

#include <OpenMesh/Core/IO/IOManager.hh>
#include <OpenMesh/Core/IO/importer/BaseImporter.hh>
#include <OpenMesh/Core/System/omstream.hh>

#include <Eigen/Geometry>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <charconv>
#include <array>
#include <thread>
#include <cstring>
#include <string_view>
#include <filesystem>

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <fstream>
#include <iterator>
#include <limits>
#include <numeric>
#include <regex>

namespace ice {

namespace {

namespace fs = std::filesystem;

// ============================================================================
// OpenMesh side: an importer that records the raw polygon soup.
// ============================================================================

/// Thrown by the importer when the reader produces more records than the file could hold
/// (a corrupt header count must not make us allocate or loop without bound).
struct RecordOverflow {};

/// Collects exactly what an OpenMesh reader hands over: positions and face index lists, no topology.
/// Every other callback (normals, colours, texture coordinates, status) is ignored.
class SoupImporter final : public OpenMesh::IO::BaseImporter {
 public:
  explicit SoupImporter(std::size_t max_records) : max_records_(max_records) {}

  std::vector<Eigen::Vector3d> points;
  PolygonList polygons;

  OpenMesh::VertexHandle add_vertex(const OpenMesh::Vec3f& p) override {
    return add_vertex(OpenMesh::Vec3d(p[0], p[1], p[2]));
  }
  OpenMesh::VertexHandle add_vertex(const OpenMesh::Vec3d& p) override {
    if (points.size() >= max_records_) throw RecordOverflow{};
    points.emplace_back(p[0], p[1], p[2]);
    return OpenMesh::VertexHandle(static_cast<int>(points.size() - 1));
  }
  OpenMesh::VertexHandle add_vertex() override { return add_vertex(OpenMesh::Vec3d(0, 0, 0)); }
  void set_point(OpenMesh::VertexHandle vh, const OpenMesh::Vec3f& p) override {
    if (vh.is_valid() && static_cast<std::size_t>(vh.idx()) < points.size())
      points[vh.idx()] = Eigen::Vector3d(p[0], p[1], p[2]);
  }
  OpenMesh::FaceHandle add_face(const VHandles& corners) override {
    if (polygons.size() >= max_records_) throw RecordOverflow{};
    std::vector<int> poly;
    poly.reserve(corners.size());
    for (const auto& vh : corners) poly.push_back(vh.idx());  // unchecked on purpose: validation sees it
    polygons.push_back(poly);
    return OpenMesh::FaceHandle(static_cast<int>(polygons.size() - 1));
  }
  void reserve(unsigned int nv, unsigned int /*ne*/, unsigned int nf) override {
    // Header counts are untrusted: never reserve more than the file could hold.
    points.reserve(std::min<std::size_t>(nv, max_records_));
    polygons.reserve(std::min<std::size_t>(nf, max_records_), 3 * std::min<std::size_t>(nf, max_records_));
  }
  std::size_t n_vertices() const override { return points.size(); }
  std::size_t n_faces() const override { return polygons.size(); }
  std::size_t n_edges() const override { return 0; }

  // Half-edge level construction is only used by the OM format, which needs a kernel(): unsupported.
  OpenMesh::HalfedgeHandle add_edge(OpenMesh::VertexHandle, OpenMesh::VertexHandle) override { return OpenMesh::HalfedgeHandle(); }
  OpenMesh::FaceHandle add_face(OpenMesh::HalfedgeHandle) override { return OpenMesh::FaceHandle(); }
  void set_halfedge(OpenMesh::VertexHandle, OpenMesh::HalfedgeHandle) override {}
  void set_next(OpenMesh::HalfedgeHandle, OpenMesh::HalfedgeHandle) override {}
  void set_face(OpenMesh::HalfedgeHandle, OpenMesh::FaceHandle) override {}

  // Attributes ICE does not use.
  void add_face_texcoords(OpenMesh::FaceHandle, OpenMesh::VertexHandle, const std::vector<OpenMesh::Vec2f>&) override {}
  void add_face_texcoords(OpenMesh::FaceHandle, OpenMesh::VertexHandle, const std::vector<OpenMesh::Vec3f>&) override {}
  void set_face_texindex(OpenMesh::FaceHandle, int) override {}
  void set_normal(OpenMesh::VertexHandle, const OpenMesh::Vec3f&) override {}
  void set_normal(OpenMesh::VertexHandle, const OpenMesh::Vec3d&) override {}
  void set_color(OpenMesh::VertexHandle, const OpenMesh::Vec3uc&) override {}
  void set_color(OpenMesh::VertexHandle, const OpenMesh::Vec4uc&) override {}
  void set_color(OpenMesh::VertexHandle, const OpenMesh::Vec3f&) override {}
  void set_color(OpenMesh::VertexHandle, const OpenMesh::Vec4f&) override {}
  void set_texcoord(OpenMesh::VertexHandle, const OpenMesh::Vec2f&) override {}
  void set_status(OpenMesh::VertexHandle, const OpenMesh::Attributes::StatusInfo&) override {}
  void request_face_texcoords2D() override {}
  void set_texcoord(OpenMesh::HalfedgeHandle, const OpenMesh::Vec2f&) override {}
  void set_texcoord(OpenMesh::VertexHandle, const OpenMesh::Vec3f&) override {}
  void set_texcoord(OpenMesh::HalfedgeHandle, const OpenMesh::Vec3f&) override {}
  void set_status(OpenMesh::HalfedgeHandle, const OpenMesh::Attributes::StatusInfo&) override {}
  void set_color(OpenMesh::EdgeHandle, const OpenMesh::Vec3uc&) override {}
  void set_color(OpenMesh::EdgeHandle, const OpenMesh::Vec4uc&) override {}
  void set_color(OpenMesh::EdgeHandle, const OpenMesh::Vec3f&) override {}
  void set_color(OpenMesh::EdgeHandle, const OpenMesh::Vec4f&) override {}
  void set_status(OpenMesh::EdgeHandle, const OpenMesh::Attributes::StatusInfo&) override {}
  void set_normal(OpenMesh::FaceHandle, const OpenMesh::Vec3f&) override {}
  void set_normal(OpenMesh::FaceHandle, const OpenMesh::Vec3d&) override {}
  void set_color(OpenMesh::FaceHandle, const OpenMesh::Vec3uc&) override {}
  void set_color(OpenMesh::FaceHandle, const OpenMesh::Vec4uc&) override {}
  void set_color(OpenMesh::FaceHandle, const OpenMesh::Vec3f&) override {}
  void set_color(OpenMesh::FaceHandle, const OpenMesh::Vec4f&) override {}
  void set_status(OpenMesh::FaceHandle, const OpenMesh::Attributes::StatusInfo&) override {}
  void add_texture_information(int, std::string) override {}

 private:
  std::size_t max_records_;
};

/// Silences OpenMesh's console streams for the lifetime of the guard (errors become MeshError instead).
class QuietOpenMesh {
 public:
  QuietOpenMesh() : err_(::omerr().is_enabled()), log_(::omlog().is_enabled()),
                    out_(::omout().is_enabled()) {
    ::omerr().disable();
    ::omlog().disable();
    ::omout().disable();
  }
  ~QuietOpenMesh() {
    if (err_) ::omerr().enable();
    if (log_) ::omlog().enable();
    if (out_) ::omout().enable();
  }
  QuietOpenMesh(const QuietOpenMesh&) = delete;
  QuietOpenMesh& operator=(const QuietOpenMesh&) = delete;

 private:
  bool err_, log_, out_;
};

PolygonSoup read_with_openmesh(const std::string& path, std::size_t max_records) {
  SoupImporter importer(max_records);
  OpenMesh::IO::Options options;  // positions and faces only
  bool ok = false;
  {
    QuietOpenMesh quiet;
    try {
      ok = OpenMesh::IO::IOManager().read(path, importer, options);
    } catch (const RecordOverflow&) {
      throw MeshError(MeshError::Kind::Unreadable, path,
                      "corrupt file: the reader produced more records than the file size allows");
    } catch (const std::exception& e) {
      throw MeshError(MeshError::Kind::Unreadable, path, std::string("cannot be parsed: ") + e.what());
    }
  }
  if (!ok) throw MeshError(MeshError::Kind::Unreadable, path, "cannot be parsed by OpenMesh's reader");
  PolygonSoup soup;
  soup.V.resize(static_cast<Eigen::Index>(importer.points.size()), 3);
  for (std::size_t i = 0; i < importer.points.size(); ++i) soup.V.row(i) = importer.points[i];
  soup.polygons = std::move(importer.polygons);
  return soup;
}

// ============================================================================
// Exact re-reading of text records.
// ============================================================================

[[noreturn]] void fail(const std::string& path, const std::string& message) {
  throw MeshError(MeshError::Kind::Unreadable, path, message);
}

/// Parse a whole token as a double (accepts nan/inf so that validation can report them). from_chars
/// first (correctly rounded, like strtod, and without its locale and copying costs); what it does
/// not take whole (a leading '+', hexadecimal, overflow or underflow) goes to strtod, whose result
/// is kept (overflow to ±inf is kept and reported as non-finite).
bool parse_double(std::string_view token, double& value) {
  if (token.empty()) return false;
  const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), value);
  if (error == std::errc() && end == token.data() + token.size()) return true;
  const std::string text(token);
  char* text_end = nullptr;
  errno = 0;
  value = std::strtod(text.c_str(), &text_end);
  return text_end == text.c_str() + text.size();
}

/// Parse a whole token as an integer; values beyond long long become its maximum (out of range).
bool parse_int(std::string_view token, long long& value) {
  if (token.empty()) return false;
  const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), value);
  if (error == std::errc() && end == token.data() + token.size()) return true;
  const std::string text(token);
  char* text_end = nullptr;
  errno = 0;
  value = std::strtoll(text.c_str(), &text_end, 10);
  if (text_end != text.c_str() + text.size()) return false;
  if (errno == ERANGE) value = std::numeric_limits<long long>::max();
  return true;
}

int clamp_index(long long value) {
  // Anything outside int is out of range anyway; -1 keeps it recognisably invalid.
  if (value < 0 || value > std::numeric_limits<int>::max()) return -1;
  return static_cast<int>(value);
}

/// Whitespace as `std::istream >> std::string` sees it in the C locale.
bool is_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\v' || c == '\f' || c == '\r'; }

/// The tokens of one line, up to a '#' comment, one at a time (no allocation).
class LineTokens {
 public:
  /// `comments`: '#' starts a comment (OBJ, OFF); PLY data has none.
  explicit LineTokens(std::string_view line, bool comments = true)
      : rest_(comments ? line.substr(0, line.find('#')) : line) {}
  bool next(std::string_view& token) {
    std::size_t i = 0;
    while (i < rest_.size() && is_space(rest_[i])) ++i;
    if (i == rest_.size()) return false;
    std::size_t j = i;
    while (j < rest_.size() && !is_space(rest_[j])) ++j;
    token = rest_.substr(i, j - i);
    rest_ = rest_.substr(j);
    return true;
  }

 private:
  std::string_view rest_;
};

/// Replaces `tokens` by the whitespace-separated tokens of `line` before any '#' (views into it).
void tokenize(std::string_view line, std::vector<std::string_view>& tokens) {
  tokens.clear();
  LineTokens line_tokens(line);
  for (std::string_view token; line_tokens.next(token);) tokens.push_back(token);
}

/// The tokens of one text line as strings, after any '#' comment is removed if `comments`.
std::vector<std::string> line_tokens(std::string_view line, bool comments = true) {
  std::vector<std::string> tokens;
  LineTokens all(line, comments);
  for (std::string_view token; all.next(token);) tokens.emplace_back(token);
  return tokens;
}

/// Whether a line holds a token (before any '#' comment if `comments`).
bool has_token(std::string_view line, bool comments = true) {
  std::string_view token;
  return LineTokens(line, comments).next(token);
}

/// Whether a number read as a double is a whole number that fits a long long (PLY list lengths
/// and vertex indices, whatever their declared type, are read as doubles first).
bool whole_number(double value) { return std::abs(value) < 9.2e18 && value == std::floor(value); }

/// The bytes of a file from `offset` on, scanned in place by the readers: mapped read-only (no copy;
/// reading 170 MB into a string took 0.25 s of a 1.6M-vertex load), or read into memory when the
/// file cannot be mapped.
class FileBytes {
 public:
  FileBytes(const std::string& path, std::size_t offset = 0) {
    const int fd = ::open(path.c_str(), O_RDONLY);
    if (fd < 0) fail(path, "cannot be opened");
    struct stat status;
    if (::fstat(fd, &status) == 0 && status.st_size > 0) {
      void* mapped = ::mmap(nullptr, static_cast<std::size_t>(status.st_size), PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
      if (mapped != MAP_FAILED) {
        mapped_ = mapped;
        mapped_size_ = static_cast<std::size_t>(status.st_size);
        view_ = std::string_view(static_cast<const char*>(mapped), mapped_size_);
      }
    }
    ::close(fd);
    if (!mapped_) {
      std::ifstream in(path, std::ios::binary);
      if (!in) fail(path, "cannot be opened");
      copy_.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
      if (in.bad()) fail(path, "read error");
      view_ = copy_;
    }
    view_ = view_.substr(std::min(offset, view_.size()));
  }
  ~FileBytes() {
    if (mapped_) ::munmap(mapped_, mapped_size_);
  }
  FileBytes(const FileBytes&) = delete;
  FileBytes& operator=(const FileBytes&) = delete;
  std::string_view view() const { return view_; }

 private:
  void* mapped_ = nullptr;
  std::size_t mapped_size_ = 0;
  std::string copy_;
  std::string_view view_;
};

/// std::getline over bytes in memory: lines end at '\n' (kept out), the last one may lack it.
class TextLines {
 public:
  explicit TextLines(std::string_view text) : text_(text) {}
  /// The next line; false when none is left. number() is its 1-based number.
  bool next(std::string_view& line) {
    if (position_ >= text_.size()) return false;
    const std::size_t end = std::min(text_.find('\n', position_), text_.size());
    line = text_.substr(position_, end - position_);
    position_ = end + 1;
    ++number_;
    return true;
  }
  std::size_t number() const { return number_; }
  /// The byte offset of the next line.
  std::size_t offset() const { return position_; }

 private:
  std::string_view text_;
  std::size_t position_ = 0, number_ = 0;
};

/// Text files of one record per line are parsed in chunks of whole lines on several threads: a
/// first pass counts each chunk's lines and records (of up to two kinds), a second parses each
/// chunk knowing its first line number and its first record of each kind. Results, messages and
/// the error reported (the first in the file) do not depend on the chunking.
struct TextChunk {
  std::size_t begin = 0, end = 0;               ///< Byte range of whole lines.
  std::size_t lines = 0, first_line = 0;        ///< Its line count and its first line's number (1-based).
  std::array<std::size_t, 2> records{}, first_record{};
};

/// Files below this size are read on one thread (starting threads costs more than it saves).
constexpr std::size_t kParallelTextBytes = std::size_t(1) << 22;

int text_threads(std::size_t bytes) { return detail::threads_for(bytes, kParallelTextBytes); }

/// Cuts text[begin, size) into chunks of whole lines, counts each one's lines and records (`kind_of`
/// a line: 0, 1 or -1 for none) on `threads` threads, and numbers them: the first chunk's first line
/// is `first_line`.
template <class KindOf>
std::vector<TextChunk> count_text_chunks(std::string_view text, std::size_t begin, std::size_t first_line,
                                         int threads, KindOf&& kind_of) {
  const int parts = threads > 1 ? 4 * threads : 1;
  std::vector<TextChunk> chunks;
  std::size_t at = begin;
  for (int c = 0; c < parts && at < text.size(); ++c) {
    std::size_t end = c + 1 == parts ? text.size() : at + (text.size() - begin) / static_cast<std::size_t>(parts);
    if (end < text.size()) {
      const std::size_t newline = text.find('\n', std::max(end, at));
      end = newline == std::string_view::npos ? text.size() : newline + 1;
    }
    end = std::max(end, at);
    chunks.push_back({at, end});
    at = end;
  }
  detail::run_tasks(threads, static_cast<int>(chunks.size()), [&](int c) {
    TextChunk& chunk = chunks[c];
    TextLines lines(text.substr(chunk.begin, chunk.end - chunk.begin));
    std::string_view line;
    while (lines.next(line)) {
      const int kind = kind_of(line);
      if (kind >= 0) ++chunk.records[kind];
    }
    chunk.lines = lines.number();
  });
  std::size_t line = first_line;
  std::array<std::size_t, 2> record{};
  for (TextChunk& chunk : chunks) {
    chunk.first_line = line;
    chunk.first_record = record;
    line += chunk.lines;
    for (int k = 0; k < 2; ++k) record[k] += chunk.records[k];
  }
  return chunks;
}

/// The records of one kind in all chunks.
std::size_t total_records(const std::vector<TextChunk>& chunks, int kind) {
  std::size_t total = 0;
  for (const TextChunk& chunk : chunks) total += chunk.records[static_cast<std::size_t>(kind)];
  return total;
}

/// Faces parsed by one chunk: corner lists, appended to the soup in chunk order.
struct ChunkFaces {
  std::vector<int> corners;
  std::vector<std::uint32_t> sizes;
};

void append_faces(PolygonList& polygons, const std::vector<ChunkFaces>& parts) {
  std::size_t faces = polygons.size(), corners = polygons.corner_count();
  for (const ChunkFaces& part : parts) faces += part.sizes.size(), corners += part.corners.size();
  polygons.reserve(faces, corners);
  for (const ChunkFaces& part : parts) {
    const int* corner = part.corners.data();
    for (std::uint32_t size : part.sizes) {
      polygons.push_back(PolygonList::Corners<const int>(corner, corner + size));
      corner += size;
    }
  }
}

/// OBJ: every `v` line (x y z [w|r g b]) and every `f` line (vertex index before any '/'), 1-based,
/// negative indices relative to the vertices read so far, as the OBJ specification says.
PolygonSoup read_obj_exact(const std::string& path) {
  const FileBytes file(path);
  const std::string_view bytes = file.view();
  const auto kind_of = [](std::string_view line) {  // 0: a `v` line, 1: an `f` line
    std::size_t i = 0;
    while (i < line.size() && is_space(line[i])) ++i;
    if (i == line.size() || (line[i] != 'v' && line[i] != 'f')) return -1;
    if (i + 1 < line.size() && !is_space(line[i + 1])) return -1;  // vn, vt, ...
    return line[i] == 'v' ? 0 : 1;
  };
  const int threads = text_threads(bytes.size());
  const std::vector<TextChunk> chunks = count_text_chunks(bytes, 0, 1, threads, kind_of);
  const std::size_t nv = total_records(chunks, 0);
  PolygonSoup soup;
  soup.V.resize(static_cast<Eigen::Index>(nv), 3);
  std::vector<ChunkFaces> faces(chunks.size());
  detail::run_tasks(threads, static_cast<int>(chunks.size()), [&](int c) {
    const TextChunk& chunk = chunks[c];
    TextLines lines(bytes.substr(chunk.begin, chunk.end - chunk.begin));
    std::string_view line, token;
    long long vertices_so_far = static_cast<long long>(chunk.first_record[0]);
    while (lines.next(line)) {
      const int kind = kind_of(line);
      if (kind < 0) continue;
      const auto where = [&] { return "line " + std::to_string(chunk.first_line + lines.number() - 1) + ": "; };
      LineTokens tokens(line);
      tokens.next(token);  // "v" or "f"
      if (kind == 0) {
        double p[3];
        for (double& x : p)
          if (!tokens.next(token) || !parse_double(token, x)) {
            std::string text(line);
            const auto hash = text.find('#');
            if (hash != std::string::npos) text.erase(hash);
            fail(path, where() + "vertex needs three numbers: '" + text + "'");
          }
        for (int k = 0; k < 3; ++k) soup.V(vertices_so_far, k) = p[k];
        ++vertices_so_far;
      } else {
        ChunkFaces& out = faces[c];
        std::uint32_t size = 0;
        while (tokens.next(token)) {
          long long value;
          if (!parse_int(token.substr(0, token.find('/')), value))
            fail(path, where() + "bad face corner '" + std::string(token) + "'");
          if (value < 0)
            value += vertices_so_far;  // -1 is the last vertex so far
          else
            value -= 1;  // 1-based; 0 becomes -1, which is invalid
          out.corners.push_back(clamp_index(value));
          ++size;
        }
        out.sizes.push_back(size);
      }
    }
  });
  append_faces(soup.polygons, faces);
  return soup;
}

/// A point set as text (.xyz, .pwn): one point a line, its first three numbers the position (more, such
/// as a normal or a colour, are read past); '#' comments and blank lines skipped; a first line holding
/// one whole number only (a point count, as some writers put) is skipped too.
PolygonSoup read_xyz_exact(const std::string& path) {
  const FileBytes file(path);
  const std::string_view bytes = file.view();
  std::size_t begin = 0, first_line = 1;
  {
    TextLines lines(bytes);
    std::string_view line;
    while (lines.next(line)) {
      const std::vector<std::string> tokens = line_tokens(line);
      if (tokens.empty()) continue;
      long long count;
      if (tokens.size() == 1 && parse_int(tokens[0], count)) {
        begin = std::min(lines.offset(), bytes.size());
        first_line = lines.number() + 1;
      }
      break;
    }
  }
  const auto kind_of = [](std::string_view line) { return has_token(line) ? 0 : -1; };
  const int threads = text_threads(bytes.size());
  const std::vector<TextChunk> chunks = count_text_chunks(bytes, begin, first_line, threads, kind_of);
  PolygonSoup soup;
  soup.V.resize(static_cast<Eigen::Index>(total_records(chunks, 0)), 3);
  detail::run_tasks(threads, static_cast<int>(chunks.size()), [&](int c) {
    const TextChunk& chunk = chunks[c];
    TextLines lines(bytes.substr(chunk.begin, chunk.end - chunk.begin));
    std::string_view line, token;
    auto point = static_cast<Eigen::Index>(chunk.first_record[0]);
    while (lines.next(line)) {
      if (kind_of(line) < 0) continue;
      LineTokens tokens(line);
      for (int k = 0; k < 3; ++k) {
        double x;
        if (!tokens.next(token) || !parse_double(token, x))
          fail(path, "line " + std::to_string(chunk.first_line + lines.number() - 1) +
                         ": a point needs three numbers: '" + std::string(line.substr(0, line.find('#'))) + "'");
        soup.V(point, k) = x;
      }
      ++point;
    }
  });
  return soup;
}

/// A token as it may be shown in a message: at most 40 characters, bytes outside printable ASCII as \xNN.
std::string printable(const std::string& token) {
  std::string text;
  for (std::size_t i = 0; i < token.size() && i < 40; ++i) {
    const auto byte = static_cast<unsigned char>(token[i]);
    if (byte >= 0x20 && byte < 0x7f) {
      text += static_cast<char>(byte);
    } else {
      static const char* hex = "0123456789abcdef";
      text += "\\x";
      text += hex[byte >> 4];
      text += hex[byte & 15];
    }
  }
  return token.size() > 40 ? text + "..." : text;
}

/// Byte-order aware read of one binary scalar (PLY, binary OFF) of `size` bytes as double; `is_float`
/// for float/double.
double decode_binary_scalar(const unsigned char* p, std::size_t size, bool is_float, bool is_signed, bool big_endian) {
  unsigned char b[8];
  for (std::size_t i = 0; i < size; ++i) b[i] = big_endian ? p[size - 1 - i] : p[i];  // host is little endian
  auto as = [&](auto tag) {
    decltype(tag) v;
    std::memcpy(&v, b, sizeof v);
    return static_cast<double>(v);
  };
  if (is_float) return size == 4 ? as(float{}) : as(double{});
  switch (size) {
    case 1: return is_signed ? as(std::int8_t{}) : as(std::uint8_t{});
    case 2: return is_signed ? as(std::int16_t{}) : as(std::uint16_t{});
    default: return is_signed ? as(std::int32_t{}) : as(std::uint32_t{});
  }
}

/// What an OFF keyword ([ST][C][N][4][n]OFF, Geomview's grammar) says each vertex record carries.
struct OffLayout {
  bool texture = false, color = false, normal = false;
};

/// Reads the keyword, or fails naming it: every OFF file is read here, never by OpenMesh, whose ASCII
/// reader loops for minutes and allocates gigabytes on some corrupt files (found by fuzzing).
OffLayout parse_off_keyword(const std::string& path, const std::string& keyword) {
  OffLayout layout;
  std::size_t i = 0;
  if (keyword.compare(i, 2, "ST") == 0) layout.texture = true, i += 2;
  if (i < keyword.size() && keyword[i] == 'C') layout.color = true, ++i;
  if (i < keyword.size() && keyword[i] == 'N') layout.normal = true, ++i;
  const std::string rest = keyword.substr(i);
  if (rest == "OFF") return layout;
  if (rest == "4OFF" || rest == "nOFF" || rest == "4nOFF")
    fail(path, "'" + keyword + "' (homogeneous or n-dimensional vertices) is not supported: write plain 3D OFF");
  fail(path, "not an OFF file: the first keyword must be OFF, COFF, NOFF, STOFF or the like, found '" +
                 printable(keyword) + "'");
}

/// Geomview's binary OFF (keyword line "OFF BINARY"): 32-bit vertex, face and edge counts, then per vertex
/// 32-bit floats (x y z, then normal, colour RGBA and texture coordinates as the keyword says), per face
/// a corner count, the indices and a colour count (0–4) with that many 32-bit values. Geomview writes big
/// endian; OpenMesh writes the host's (little endian) order. The byte order whose counts fit the file
/// is used, big endian first.
PolygonSoup read_off_binary(const std::string& path, std::streamoff data_offset, const OffLayout& layout) {
  std::ifstream in(path, std::ios::binary);
  in.seekg(data_offset);
  const std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  bool big_endian = true;
  auto int_at = [&](std::size_t offset, bool big) {
    return static_cast<long long>(decode_binary_scalar(&bytes[offset], 4, false, true, big));
  };
  std::size_t at = 0;
  auto next = [&](bool is_float) {
    if (at + 4 > bytes.size()) fail(path, "binary OFF data ends early (at byte " + std::to_string(at) + " of the data)");
    at += 4;
    return decode_binary_scalar(&bytes[at - 4], 4, is_float, true, big_endian);
  };
  auto next_count = [&](const char* what, std::size_t min_bytes_each) -> std::size_t {
    const auto value = static_cast<long long>(next(false));
    const std::string where = std::string(what) + " " + std::to_string(value) + " at byte " + std::to_string(at - 4);
    if (value < 0) fail(path, "binary OFF: negative " + where + " of the data");
    if (static_cast<std::size_t>(value) > (bytes.size() - at) / min_bytes_each)
      fail(path, "binary OFF data ends early or is corrupt: " + where + " of the data asks for more bytes than are left");
    return static_cast<std::size_t>(value);
  };
  const std::size_t floats_per_vertex = 3 + (layout.normal ? 3 : 0) + (layout.color ? 4 : 0) + (layout.texture ? 2 : 0);
  if (bytes.size() < 12) fail(path, "binary OFF data ends before the vertex, face and edge counts");
  auto counts_fit = [&](bool big) {
    const long long nv = int_at(0, big), nf = int_at(4, big);
    return nv >= 0 && nf >= 0 &&
           static_cast<std::uint64_t>(nv) * 4 * floats_per_vertex + static_cast<std::uint64_t>(nf) * 8 <= bytes.size();
  };
  big_endian = counts_fit(true) || !counts_fit(false);
  const std::size_t nv = next_count("vertex count", 4 * floats_per_vertex);
  const std::size_t nf = next_count("face count", 8);
  next(false);  // edge count: unused
  PolygonSoup soup;
  soup.V.resize(static_cast<Eigen::Index>(nv), 3);
  for (std::size_t v = 0; v < nv; ++v)
    for (std::size_t k = 0; k < floats_per_vertex; ++k) {
      const double value = next(true);
      if (k < 3) soup.V(static_cast<Eigen::Index>(v), static_cast<Eigen::Index>(k)) = value;
    }
  soup.polygons.reserve(nf, 3 * nf);
  std::vector<int> poly;
  for (std::size_t f = 0; f < nf; ++f) {
    const std::size_t corners = next_count("face corner count", 4);
    poly.clear();
    for (std::size_t c = 0; c < corners; ++c) poly.push_back(clamp_index(static_cast<long long>(next(false))));
    soup.polygons.push_back(poly);
    const std::size_t colors = next_count("face colour count", 4);
    if (colors > 4) fail(path, "binary OFF: face " + std::to_string(f) + " has " + std::to_string(colors) + " colour values (at most 4)");
    at += 4 * colors;
  }
  return soup;
}

/// OFF, ASCII ([ST][C][N]OFF: one vertex per line, x y z first; one face per line, k i1 .. ik first) or
/// binary ("OFF BINARY"). Any other keyword is refused with its text.
PolygonSoup read_off_exact(const std::string& path, std::uintmax_t file_size) {
  {
    // The keyword line (comments before it are skipped) says whether binary data follows it.
    std::ifstream in(path, std::ios::binary);
    if (!in) fail(path, "cannot be opened");
    std::string line;
    std::vector<std::string> keyword_line;
    while (keyword_line.empty() && std::getline(in, line)) keyword_line = line_tokens(line);
    if (keyword_line.empty()) fail(path, "no OFF data");
    const OffLayout layout = parse_off_keyword(path, keyword_line[0]);
    if (keyword_line.size() > 1 && keyword_line[1] == "BINARY") return read_off_binary(path, in.tellg(), layout);
  }
  // The header (keyword line, counts on it or on the next non-empty line), then the records: one
  // per non-empty line (after '#' comments), counted first so that a short file is named as such
  // before any record is parsed.
  const FileBytes file(path);
  const std::string_view bytes = file.view();
  TextLines lines(bytes);
  std::string_view line;
  std::vector<std::string_view> tokens;
  const auto next_tokens = [&] {  // the next non-empty line into `tokens`; false at the end
    while (lines.next(line)) {
      tokenize(line, tokens);
      if (!tokens.empty()) return true;
    }
    return false;
  };
  next_tokens();  // the keyword line
  std::vector<std::string_view> header(tokens.begin() + 1, tokens.end());
  if (header.size() < 2) {
    if (!next_tokens()) fail(path, "OFF header has no vertex and face counts");
    header = tokens;
  }
  long long nv, nf;
  if (header.size() < 2 || !parse_int(header[0], nv) || !parse_int(header[1], nf) || nv < 0 || nf < 0)
    fail(path, "OFF header needs non-negative vertex and face counts");
  if (static_cast<std::uintmax_t>(nv) > file_size || static_cast<std::uintmax_t>(nf) > file_size)
    fail(path, "OFF header announces more elements than the file can hold");
  const std::size_t data_begin = std::min(lines.offset(), bytes.size());
  const int threads = text_threads(bytes.size());
  const std::vector<TextChunk> chunks = count_text_chunks(bytes, data_begin, lines.number() + 1, threads,
                                                          [](std::string_view l) { return has_token(l) ? 0 : -1; });
  if (total_records(chunks, 0) < static_cast<std::size_t>(nv) + static_cast<std::size_t>(nf))
    fail(path, "file ends early: the header announces " + std::to_string(nv) + " vertices and " +
                   std::to_string(nf) + " faces");
  PolygonSoup soup;
  soup.V.resize(nv, 3);
  std::vector<ChunkFaces> faces(chunks.size());
  const auto vertices = static_cast<std::size_t>(nv), wanted = vertices + static_cast<std::size_t>(nf);
  detail::run_tasks(threads, static_cast<int>(chunks.size()), [&](int c) {
    const TextChunk& chunk = chunks[c];
    if (chunk.first_record[0] >= wanted) return;  // trailing records are ignored
    TextLines chunk_lines(bytes.substr(chunk.begin, chunk.end - chunk.begin));
    std::string_view text, token;
    std::size_t record = chunk.first_record[0];
    while (record < wanted && chunk_lines.next(text)) {
      if (!has_token(text)) continue;
      const auto where = [&] { return "line " + std::to_string(chunk.first_line + chunk_lines.number() - 1) + ": "; };
      LineTokens line_tokens(text);
      if (record < vertices) {
        const auto row = static_cast<Eigen::Index>(record);
        for (Eigen::Index k = 0; k < 3; ++k)
          if (!line_tokens.next(token) || !parse_double(token, soup.V(row, k))) fail(path, where() + "vertex needs three numbers");
      } else {
        long long k;
        line_tokens.next(token);
        if (!parse_int(token, k) || k < 0 || static_cast<std::uintmax_t>(k) > text.size())
          fail(path, where() + "face needs a corner count and that many indices");
        ChunkFaces& out = faces[c];
        for (long long corner = 0; corner < k; ++corner) {
          long long value;
          if (!line_tokens.next(token)) fail(path, where() + "face needs a corner count and that many indices");
          if (!parse_int(token, value)) fail(path, where() + "bad face index");
          out.corners.push_back(clamp_index(value));
        }
        out.sizes.push_back(static_cast<std::uint32_t>(k));
      }
      ++record;
    }
  });
  append_faces(soup.polygons, faces);
  return soup;
}

/// PLY header: elements with their properties.
struct PlyProperty {
  std::string name, type, count_type;  // count_type non-empty for lists
};
struct PlyElement {
  std::string name;
  std::size_t count = 0;
  std::vector<PlyProperty> properties;
};
struct PlyHeader {
  std::string format;  // ascii, binary_little_endian, binary_big_endian
  std::vector<PlyElement> elements;
  std::streamoff data_offset = 0;
};

std::size_t ply_type_size(const std::string& type) {
  if (type == "char" || type == "uchar" || type == "int8" || type == "uint8") return 1;
  if (type == "short" || type == "ushort" || type == "int16" || type == "uint16") return 2;
  if (type == "int" || type == "uint" || type == "int32" || type == "uint32" || type == "float" || type == "float32")
    return 4;
  if (type == "double" || type == "float64") return 8;
  return 0;
}

PlyHeader read_ply_header(const std::string& path, std::uintmax_t file_size) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  if (!std::getline(in, line) || line.rfind("ply", 0) != 0) fail(path, "not a PLY file: it must begin with the line 'ply'");
  PlyHeader header;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto tokens = line_tokens(line, false);
    if (tokens.empty()) continue;
    if (tokens[0] == "end_header") {
      header.data_offset = in.tellg();
      if (header.format.empty()) fail(path, "PLY header has no format line");
      return header;
    }
    if (tokens[0] == "format" && tokens.size() >= 2) {
      header.format = tokens[1];
    } else if (tokens[0] == "element" && tokens.size() >= 3) {
      long long count;
      if (!parse_int(tokens[2], count) || count < 0 || static_cast<std::uintmax_t>(count) > file_size)
        fail(path, "PLY element '" + tokens[1] + "' has an impossible count " + tokens[2]);
      header.elements.push_back({tokens[1], static_cast<std::size_t>(count), {}});
    } else if (tokens[0] == "property" && !header.elements.empty()) {
      if (tokens.size() >= 5 && tokens[1] == "list")
        header.elements.back().properties.push_back({tokens[4], tokens[3], tokens[2]});
      else if (tokens.size() >= 3)
        header.elements.back().properties.push_back({tokens[2], tokens[1], ""});
    }
  }
  fail(path, "PLY header has no end_header line");
}

/// ASCII PLY data read in parallel when it has one record per line, as every writer makes it: the
/// non-empty lines are counted in chunks; if they are exactly the records, each chunk parses its
/// lines as records (record r of the file is record r − (records of earlier elements) of its
/// element). Returns false — and the caller reads the token stream, which names any defect — when
/// the lines are not the records or a line is not exactly one record; every line that is parses
/// token for token as the stream reader parses it, so both give the same soup.
bool read_ply_ascii_lines(std::string_view data, const std::vector<PlyElement>& elements, const PlyElement* vertex,
                          const int* axis_of_property, std::uintmax_t file_size, PolygonSoup& soup) {
  const int threads = text_threads(data.size());
  if (threads < 2) return false;
  std::size_t total = 0;
  for (const PlyElement& element : elements) total += element.count;
  const std::vector<TextChunk> chunks =
      count_text_chunks(data, 0, 1, threads, [](std::string_view line) { return has_token(line, false) ? 0 : -1; });
  if (total_records(chunks, 0) != total) return false;
  std::vector<std::size_t> element_begin{0};  // first record of each element in the file
  for (const PlyElement& element : elements) element_begin.push_back(element_begin.back() + element.count);
  std::vector<ChunkFaces> faces(chunks.size());
  std::vector<char> parsed(chunks.size(), 0);
  detail::run_tasks(threads, static_cast<int>(chunks.size()), [&](int c) {
    const TextChunk& chunk = chunks[c];
    TextLines chunk_lines(data.substr(chunk.begin, chunk.end - chunk.begin));
    std::string_view text, token;
    std::size_t record = chunk.first_record[0];
    std::size_t e = static_cast<std::size_t>(std::upper_bound(element_begin.begin(), element_begin.end(), record) -
                                             element_begin.begin()) - 1;
    while (chunk_lines.next(text)) {
      if (!has_token(text, false)) continue;
      while (record >= element_begin[e + 1]) ++e;
      const PlyElement& element = elements[e];
      const bool is_vertex = &element == vertex, is_face = element.name == "face";
      const std::size_t index = record - element_begin[e];
      LineTokens tokens(text, false);
      const auto number = [&](double& value) { return tokens.next(token) && parse_double(token, value); };
      const auto integer = [&](long long& value) {
        double x;
        if (!number(x) || !whole_number(x)) return false;
        value = static_cast<long long>(x);
        return true;
      };
      bool took_indices = false;
      std::uint32_t corners = 0;
      for (std::size_t k = 0; k < element.properties.size(); ++k) {
        if (element.properties[k].count_type.empty()) {
          double value;
          if (!number(value)) return;
          if (is_vertex && axis_of_property[k] >= 0)
            soup.V(static_cast<Eigen::Index>(index), axis_of_property[k]) = value;
          continue;
        }
        long long length;
        if (!integer(length) || length < 0 || static_cast<std::uintmax_t>(length) > file_size) return;
        const bool indices = is_face && !took_indices;
        for (long long i = 0; i < length; ++i) {
          if (indices) {
            long long value;
            if (!integer(value)) return;
            faces[c].corners.push_back(clamp_index(value));
            ++corners;
          } else {
            double value;
            if (!number(value)) return;
          }
        }
        took_indices = took_indices || indices;
      }
      if (tokens.next(token)) return;  // more than one record on the line
      if (is_face) faces[c].sizes.push_back(corners);
      ++record;
    }
    parsed[c] = 1;
  });
  if (std::find(parsed.begin(), parsed.end(), 0) != parsed.end()) return false;
  append_faces(soup.polygons, faces);
  return true;
}

/// PLY, ASCII or binary, with its elements in any order: the `vertex` element's x, y, z (scalar
/// properties only) and the first list property of the `face` element (the vertex indices); every
/// other element and property is read past. Layouts it does not handle (no or several vertex
/// elements, a list property in the vertex element, unknown types) are refused, naming the defect.
PolygonSoup read_ply_exact(const std::string& path, std::uintmax_t file_size) {
  const PlyHeader header = read_ply_header(path, file_size);
  const bool ascii = header.format == "ascii", big_endian = header.format == "binary_big_endian";
  if (!ascii && !big_endian && header.format != "binary_little_endian")
    fail(path, "unknown PLY format '" + printable(header.format) + "'");
  const PlyElement* vertex = nullptr;
  bool has_faces = false;
  for (const PlyElement& element : header.elements) {
    for (const PlyProperty& prop : element.properties)
      if (ply_type_size(prop.type) == 0 || (!prop.count_type.empty() && ply_type_size(prop.count_type) == 0))
        fail(path, "PLY property '" + printable(prop.name) + "' of element '" + printable(element.name) +
                       "' has an unknown type '" + printable(prop.count_type.empty() ? prop.type : prop.count_type) + "'");
    if (element.name == "vertex") {
      if (vertex) fail(path, "PLY header has two vertex elements");
      vertex = &element;
    }
    if (element.name == "face") {
      if (has_faces) fail(path, "PLY header has two face elements");
      has_faces = true;
    }
  }
  if (!vertex) fail(path, "PLY header has no vertex element");
  int axis_of_property[64];  // x, y, z -> 0, 1, 2; other properties -1
  if (vertex->properties.size() > 64) fail(path, "PLY vertex element has more than 64 properties");
  int axes_found = 0;
  for (std::size_t k = 0; k < vertex->properties.size(); ++k) {
    const PlyProperty& prop = vertex->properties[k];
    if (!prop.count_type.empty()) fail(path, "PLY vertex element has a list property ('" + printable(prop.name) + "'): not supported");
    axis_of_property[k] = prop.name == "x" ? 0 : prop.name == "y" ? 1 : prop.name == "z" ? 2 : -1;
    axes_found |= axis_of_property[k] >= 0 ? 1 << axis_of_property[k] : 0;
  }
  if (axes_found != 7) fail(path, "PLY vertex element lacks one of the properties x, y, z");

  // Everything after the header, scanned in place: ASCII as whitespace-separated tokens (as
  // `std::istream >>` reads them), binary as scalars whose decoding is set up once per property.
  const FileBytes file(path, static_cast<std::size_t>(header.data_offset));
  const std::string_view data = file.view();
  const auto* bytes = reinterpret_cast<const unsigned char*>(data.data());
  std::size_t position = 0;
  std::string_view token;
  struct Scalar {
    std::size_t size = 0;
    bool is_float = false, is_signed = false;
  };
  const auto scalar_of = [](const std::string& type) {
    return Scalar{ply_type_size(type), type.rfind("float", 0) == 0 || type == "double", type[0] != 'u'};
  };
  // The next value of a scalar of `type`, in element `element` record `record`.
  const auto next_value = [&](const Scalar& type, const PlyElement& element, std::size_t record) -> double {
    const auto where = [&] { return "element '" + element.name + "' " + std::to_string(record) + " of " +
                                    std::to_string(element.count); };
    if (ascii) {
      while (position < data.size() && is_space(data[position])) ++position;
      const std::size_t start = position;
      while (position < data.size() && !is_space(data[position])) ++position;
      if (position == start) fail(path, "file ends early in " + where());
      token = data.substr(start, position - start);
      double value;
      if (!parse_double(token, value)) fail(path, where() + ": bad number '" + std::string(token) + "'");
      return value;
    }
    if (position + type.size > data.size()) fail(path, "file ends early in " + where());
    const double value = decode_binary_scalar(bytes + position, type.size, type.is_float, type.is_signed, big_endian);
    position += type.size;
    return value;
  };
  // An integer value (list length, vertex index) of a scalar of `type`.
  const auto next_integer = [&](const Scalar& type, const PlyElement& element, std::size_t record) -> long long {
    const double value = next_value(type, element, record);
    if (!whole_number(value))
      fail(path, "element '" + element.name + "' " + std::to_string(record) + ": '" +
                     (ascii ? std::string(token) : std::to_string(value)) + "' is not an integer");
    return static_cast<long long>(value);
  };

  PolygonSoup soup;
  soup.V.resize(static_cast<Eigen::Index>(vertex->count), 3);
  if (ascii && read_ply_ascii_lines(data, header.elements, vertex, axis_of_property, file_size, soup)) return soup;
  for (const PlyElement& element : header.elements) {
    const bool is_vertex = &element == vertex, is_face = element.name == "face";
    std::vector<Scalar> value_type, count_type;
    for (const PlyProperty& prop : element.properties) {
      value_type.push_back(scalar_of(prop.type));
      count_type.push_back(prop.count_type.empty() ? Scalar{} : scalar_of(prop.count_type));
    }
    if (is_face) soup.polygons.reserve(element.count, 3 * element.count);
    std::vector<int> polygon;
    for (std::size_t i = 0; i < element.count; ++i) {
      polygon.clear();
      bool took_indices = false;
      for (std::size_t k = 0; k < element.properties.size(); ++k) {
        if (count_type[k].size == 0) {
          const double value = next_value(value_type[k], element, i);
          if (is_vertex && axis_of_property[k] >= 0) soup.V(static_cast<Eigen::Index>(i), axis_of_property[k]) = value;
          continue;
        }
        const long long length = next_integer(count_type[k], element, i);
        if (length < 0 || static_cast<std::uintmax_t>(length) > file_size)
          fail(path, "element '" + element.name + "' " + std::to_string(i) + ": bad list length " + std::to_string(length));
        const bool indices = is_face && !took_indices;
        for (long long c = 0; c < length; ++c) {
          if (indices) polygon.push_back(clamp_index(next_integer(value_type[k], element, i)));
          else next_value(value_type[k], element, i);
        }
        took_indices = took_indices || indices;
      }
      if (is_face) soup.polygons.push_back(polygon);
    }
  }
  return soup;
}

std::string describe_defects(const ValidationReport& report) {
  std::string text;
  for (const auto& line : report.defects()) text += (text.empty() ? "" : "; ") + line;
  return text;
}

TriangleMesh to_triangle_mesh(const PolygonSoup& soup) {
  TriangleMesh mesh;
  mesh.V = soup.V;
  mesh.F.resize(static_cast<Eigen::Index>(soup.polygons.size()), 3);
  for (std::size_t f = 0; f < soup.polygons.size(); ++f)
    for (int k = 0; k < 3; ++k) mesh.F(f, k) = soup.polygons[f][k];
  return mesh;
}

}  // namespace

// ============================================================================

MeshFile read_mesh_file(const std::string& path) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (ec || !fs::exists(status)) fail(path, "no such file");
  if (!fs::is_regular_file(status)) fail(path, "not a regular file");
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec) fail(path, "cannot determine the file size");
  if (size == 0) fail(path, "empty file");
  if (!std::ifstream(path, std::ios::binary)) fail(path, "cannot be opened for reading");

  MeshFile file;
  file.format = lower_extension(path);
  if (file.format.empty())
    fail(path, "has no file extension: the format is taken from it (.obj, .off, .ply, .stl; points only: .xyz, .pwn)");
  if (file.format == "ilm")
    fail(path, "is an intrinsic mesh (edge lengths, no vertex positions: nothing to place or draw); give the "
               "input mesh it was made from (.obj, .off, .ply, .stl)");
  const bool points_only = file.format == "xyz" || file.format == "pwn";
  if (file.format != "obj" && file.format != "off" && file.format != "ply" && file.format != "stl" && !points_only)
    fail(path, "unsupported format '." + file.format + "' (supported: .obj, .off, .ply, .stl; points only: .xyz, .pwn)");

  // Every vertex or face record takes at least one byte: a larger count means a corrupt file.
  const std::size_t max_records = static_cast<std::size_t>(size) + 16;
  // OBJ, OFF and PLY are read completely and strictly by ICE's readers (text in double precision),
  // which refuse what they cannot read, naming it. OpenMesh reads only STL: its OFF and PLY readers
  // looped, exhausted memory or crashed on corrupt headers found by fuzzing.
  if (file.format == "stl") {
    file.soup = read_with_openmesh(path, max_records);
  } else {
    file.soup = file.format == "obj"   ? read_obj_exact(path)
                : file.format == "off" ? read_off_exact(path, size)
                : points_only          ? read_xyz_exact(path)
                                       : read_ply_exact(path, size);
    file.exact_coordinates = true;
  }
  if (file.soup.polygons.empty() && file.soup.V.rows() == 0) fail(path, "contains no vertices or faces");
  return file;
}

namespace {

// A file of points only: refused with the way to solve on it, or its points (coincident ones merged
// when repairing) with the triangles of their local Delaunay fans.
LoadResult load_point_cloud(const std::string& path, LoadResult result, const LoadOptions& options) {
  const Positions& P = result.file.soup.V;
  if (P.rows() > std::numeric_limits<Index>::max() / 8)
    throw MeshError(MeshError::Kind::Defective, path, "refused: " + std::to_string(P.rows()) + " points are too many");
  const Index n = static_cast<Index>(P.rows());
  const std::string what = "contains no faces: a point cloud of " + std::to_string(n) + " points";
  if (!options.keep_nonmanifold)
    throw MeshError(MeshError::Kind::Defective, path,
                    what + "; it can be solved on the tufted cover of its points' local Delaunay triangles "
                           "(LoadOptions::keep_nonmanifold; poisson-coarse, heat-coarse, spectral-coarse: --nonmanifold "
                           "tufted; Python: nonmanifold=\"tufted\")");
  if (!result.input_report.non_finite_vertices.first.empty())
    throw MeshError(MeshError::Kind::Defective, path,
                    "refused: point " + std::to_string(result.input_report.non_finite_vertices.first.front()) +
                        " has a coordinate that is not finite");
  // Coincident points (the validator counted them): refused, or merged into the first of them with
  // repair (repeated points add nothing to a point cloud, so no weld option is needed as for a mesh's
  // vertices).
  const auto& repeats = result.input_report.duplicate_positions;
  std::vector<int> first;  // empty: no point repeats another
  if (repeats.count > 0) {
    first = detail::first_coincident_vertex(P);
    if (!options.repair) {
      const int repeat = repeats.first.front();
      throw MeshError(MeshError::Kind::Defective, path,
                      "refused: " + std::to_string(repeats.count) + " points repeat an earlier point's position (first: point " +
                          std::to_string(repeat) + " at point " + std::to_string(first[static_cast<std::size_t>(repeat)]) +
                          "'s) (load with repair to merge them)");
    }
  }
  for (Index i = 0; i < n; ++i)
    if (first.empty() || first[static_cast<std::size_t>(i)] == i) result.source_vertex.push_back(i);
  result.repairs.welded_vertices = repeats.count;
  TriangleMesh& mesh = result.mesh;
  mesh.V.resize(static_cast<Eigen::Index>(result.source_vertex.size()), 3);
  for (std::size_t i = 0; i < result.source_vertex.size(); ++i) mesh.V.row(static_cast<Eigen::Index>(i)) = P.row(result.source_vertex[i]);
  try {
    mesh.F = point_cloud_triangles(mesh.V, options.point_cloud);
  } catch (const std::invalid_argument& error) {
    // The message without the function's name, its point numbers those of the file.
    std::string message = std::string(error.what()).substr(std::string("point_cloud_triangles: ").size()), named;
    const std::regex number(R"((points? |and )(\d+))");
    std::size_t at = 0;
    for (std::sregex_iterator it(message.begin(), message.end(), number), end; it != end; ++it) {
      const std::size_t i = std::stoul((*it)[2].str());
      named += message.substr(at, static_cast<std::size_t>(it->position()) - at) + (*it)[1].str() +
               std::to_string(i < result.source_vertex.size() ? result.source_vertex[i] : static_cast<Index>(i));
      at = static_cast<std::size_t>(it->position() + it->length());
    }
    throw MeshError(MeshError::Kind::Defective, path, "refused: " + named + message.substr(at));
  }
  result.point_cloud = true;
  result.report = validate_mesh(mesh);
  if (!result.report.clean_but_for_sheets())  // not expected: the fans are non-degenerate and distinct
    throw MeshError(MeshError::Kind::Defective, path, "refused: its points' local triangles have " + describe_defects(result.report));
  return result;
}

}  // namespace

LoadResult load_mesh_with_report(const std::string& path, const LoadOptions& options) {
  if (options.point_cloud.neighbours < 2)
    throw std::invalid_argument("LoadOptions::point_cloud.neighbours must be at least 2, not " +
                                std::to_string(options.point_cloud.neighbours));
  LoadResult result;
  result.file = read_mesh_file(path);
  result.input_report = validate_mesh(result.file.soup);
  if (result.file.soup.polygons.empty()) return load_point_cloud(path, std::move(result), options);

  const auto acceptable = [&](const ValidationReport& report) {
    return report.clean() || (options.keep_nonmanifold && report.clean_but_for_sheets());
  };
  // Defects that only the tufted cover takes (the repairs split non-manifold vertices between
  // manifold edges and re-orient orientable surfaces): the message says so.
  const auto cover_hint = [&](const ValidationReport& report) {
    const bool sheets = !report.non_manifold_edges.empty() || report.non_orientable_components > 0;
    return sheets && report.clean_but_for_sheets() && !options.keep_nonmanifold
               ? std::string("; such a mesh can be solved on its tufted cover (the tools' --nonmanifold tufted)")
               : std::string();
  };
  if (!options.repair) {
    if (!acceptable(result.input_report))
      throw MeshError(MeshError::Kind::Defective, path,
                      "refused: " + describe_defects(result.input_report) + " (load with repair to fix what is safe)" +
                          cover_hint(result.input_report));
    result.mesh = to_triangle_mesh(result.file.soup);
    result.source_vertex.resize(static_cast<std::size_t>(result.mesh.V.rows()));
    std::iota(result.source_vertex.begin(), result.source_vertex.end(), 0);
    result.source_face.resize(static_cast<std::size_t>(result.mesh.F.rows()));
    std::iota(result.source_face.begin(), result.source_face.end(), 0);
    result.report = result.input_report;
    return result;
  }

  RepairOptions repair_options;
  repair_options.weld_duplicate_positions = options.weld_duplicate_positions;
  RepairResult repaired = repair_mesh(result.file.soup, repair_options);
  result.repairs = repaired.log;
  if (!acceptable(repaired.report)) {
    std::string done;
    for (const auto& line : repaired.log.summary()) done += (done.empty() ? "" : ", ") + line;
    throw MeshError(MeshError::Kind::Defective, path,
                    "refused even after repair: " + describe_defects(repaired.report) +
                        (done.empty() ? std::string() : " (repairs done: " + done + ")") + cover_hint(repaired.report));
  }
  if (repaired.soup.polygons.empty()) throw MeshError(MeshError::Kind::Defective, path, "no faces left after repair");
  result.mesh = to_triangle_mesh(repaired.soup);
  result.source_vertex = std::move(repaired.source_vertex);
  result.source_face = std::move(repaired.source_face);
  result.report = std::move(repaired.report);
  return result;
}

ValidationReport require_clean_mesh(const TriangleMesh& mesh, const std::string& name) {
  ValidationReport report = validate_mesh(mesh);
  if (!report.clean()) throw MeshError(MeshError::Kind::Defective, name, "refused: " + describe_defects(report));
  return report;
}

TriangleMesh load_mesh(const std::string& path, const LoadOptions& options) {
  return load_mesh_with_report(path, options).mesh;
}

// ============================================================================
// Writing.
// ============================================================================

}  // namespace ice
