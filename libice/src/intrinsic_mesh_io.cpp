#include "ice/intrinsic_mesh_io.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "ice/mesh_io.h"
#include "ice/triangle_geometry.h"

namespace ice {
namespace {

// Reads the next line that is not a comment or blank, splitting it into words; false at the end.
class LineReader {
 public:
  LineReader(std::istream& in, const std::string& path) : in_(in), path_(path) {}
  bool next(std::vector<std::string>& words) {
    std::string line;
    while (std::getline(in_, line)) {
      ++number_;
      if (!line.empty() && line.back() == '\r') line.pop_back();
      const auto first = line.find_first_not_of(" \t");
      if (first == std::string::npos || line[first] == '#') continue;
      words.clear();
      std::istringstream split(line);
      for (std::string word; split >> word;) words.push_back(word);
      return true;
    }
    return false;
  }
  [[noreturn]] void fail(MeshError::Kind kind, const std::string& what) const {
    throw MeshError(kind, path_, "line " + std::to_string(number_) + ": " + what);
  }
  int line() const { return number_; }

 private:
  std::istream& in_;
  const std::string& path_;
  int number_ = 1;  // the header line was read before
};

template <class T>
bool parse(const std::string& word, T& value) {
  const char* end = word.data() + word.size();
  const auto result = std::from_chars(word.data(), end, value);
  return result.ec == std::errc() && result.ptr == end;
}

// Shortest text that reads back to the same double.
std::string shortest(double value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
  return std::string(buffer, result.ptr);
}

}  // namespace

IntrinsicMeshFile read_intrinsic_mesh(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw MeshError(MeshError::Kind::Unreadable, path, "cannot be opened");
  std::string header;
  if (!std::getline(in, header)) throw MeshError(MeshError::Kind::Unreadable, path, "empty file");
  if (!header.empty() && header.back() == '\r') header.pop_back();
  if (header != "ICE-ILM 1" && header != "ICE-ILM 2")
    throw MeshError(MeshError::Kind::Unreadable, path,
                    "not an ICE intrinsic mesh (.ilm): the first line must be \"ICE-ILM 2\" (or \"ICE-ILM 1\")");
  const int version = header.back() - '0';
  const std::size_t face_words = version == 2 ? 10 : 7;
  LineReader reader(in, path);
  std::vector<std::string> words;
  // The three counts, in order.
  long long counts[3] = {0, 0, 0};
  const char* names[3] = {"vertices", "faces", "input_vertices"};
  for (int k = 0; k < 3; ++k) {
    if (!reader.next(words)) reader.fail(MeshError::Kind::Unreadable, std::string("missing \"") + names[k] + " <count>\"");
    if (words.size() != 2 || words[0] != names[k] || !parse(words[1], counts[k]) || counts[k] < 0 ||
        counts[k] > std::numeric_limits<Index>::max())
      reader.fail(MeshError::Kind::Unreadable, std::string("expected \"") + names[k] + " <count>\"");
  }
  // A corrupt count must not make the reader allocate gigabytes: every face line takes at least 14
  // bytes ("f 0 0 0 1 1 1\n") and every vertex line 4 ("v 0\n").
  std::error_code size_error;
  const auto file_size = std::filesystem::file_size(path, size_error);
  if (!size_error && 14.0 * static_cast<double>(counts[1]) + 4.0 * static_cast<double>(counts[0]) > static_cast<double>(file_size))
    reader.fail(MeshError::Kind::Unreadable, "the counts (" + std::to_string(counts[0]) + " vertices, " +
                                                 std::to_string(counts[1]) + " faces) exceed what a file of " +
                                                 std::to_string(file_size) + " bytes can hold");
  const Index n = static_cast<Index>(counts[0]), m = static_cast<Index>(counts[1]);
  IntrinsicMeshFile file;
  file.version = version;
  file.input_vertices = static_cast<Index>(counts[2]);
  if (version == 2) file.twin.resize(static_cast<std::size_t>(3 * m));
  std::vector<int> face_line(static_cast<std::size_t>(m));
  if (m == 0) reader.fail(MeshError::Kind::Defective, "the mesh has no faces");
  file.F.resize(m, 3);
  file.L.resize(m, 3);
  std::vector<char> used(static_cast<std::size_t>(n), 0);
  for (Index f = 0; f < m; ++f) {
    if (!reader.next(words)) reader.fail(MeshError::Kind::Unreadable, "file ends after " + std::to_string(f) + " of " + std::to_string(m) + " faces");
    face_line[static_cast<std::size_t>(f)] = reader.line();
    if (words.size() != face_words || words[0] != "f")
      reader.fail(MeshError::Kind::Unreadable, std::string("expected \"f i j k l_ij l_jk l_ki") +
                                                   (version == 2 ? " t_ij t_jk t_ki" : "") + "\" (face " +
                                                   std::to_string(f) + ")");
    for (int c = 0; c < 3; ++c) {
      long long id = 0;
      if (!parse(words[1 + c], id)) reader.fail(MeshError::Kind::Unreadable, "face " + std::to_string(f) + ": bad vertex id \"" + words[1 + c] + "\"");
      if (id < 0 || id >= n)
        reader.fail(MeshError::Kind::Defective, "face " + std::to_string(f) + ": vertex " + std::to_string(id) +
                                                    " out of range (" + std::to_string(n) + " vertices)");
      file.F(f, c) = static_cast<int>(id);
      used[static_cast<std::size_t>(id)] = 1;
      double length = 0;
      if (!parse(words[4 + c], length)) reader.fail(MeshError::Kind::Unreadable, "face " + std::to_string(f) + ": bad length \"" + words[4 + c] + "\"");
      if (!(length > 0) || !std::isfinite(length))
        reader.fail(MeshError::Kind::Defective, "face " + std::to_string(f) + ": edge length " + words[4 + c] + " is not positive and finite");
      file.L(f, c) = length;
    }
    if (!triangle_inequality_holds(file.L(f, 0), file.L(f, 1), file.L(f, 2)))
      reader.fail(MeshError::Kind::Defective, "face " + std::to_string(f) + ": lengths violate the triangle inequality");
    for (int c = 0; version == 2 && c < 3; ++c) {
      long long side = 0;
      if (!parse(words[7 + c], side)) reader.fail(MeshError::Kind::Unreadable, "face " + std::to_string(f) + ": bad twin \"" + words[7 + c] + "\"");
      if (side < -1 || side >= 3 * static_cast<long long>(m) || side == 3 * static_cast<long long>(f) + c)
        reader.fail(MeshError::Kind::Defective, "face " + std::to_string(f) + ": twin " + words[7 + c] + " of side " +
                                                    std::to_string(c) + " is out of range or the side itself");
      file.twin[static_cast<std::size_t>(3 * f + c)] = side < 0 ? kInvalid : static_cast<Index>(side);
    }
  }
  // The gluing: symmetric, joining sides with the same ends run opposite ways, of one length (the
  // writer writes one double per edge). Each twin is in range and not its own side: checked as read.
  if (const GluingCheck glued = file.twin.empty() ? GluingCheck{} : first_gluing_defect(file.F, file.L, file.twin);
      glued.defect != GluingDefect::none) {
    const Index f = glued.side / 3;
    const char* why = glued.defect == GluingDefect::not_glued_back ? ", which is not glued back"
                      : glued.defect == GluingDefect::other_ends   ? ", whose end vertices differ"
                                                                   : " of another length";
    throw MeshError(MeshError::Kind::Defective, path,
                    "line " + std::to_string(face_line[static_cast<std::size_t>(f)]) + ": face " + std::to_string(f) + ", side " +
                        std::to_string(glued.side % 3) + " is glued to side " + std::to_string(glued.other) + why);
  }
  file.to_input.resize(static_cast<std::size_t>(n));
  file.vertex_count = static_cast<Index>(n);
  for (Index v = 0; v < n; ++v) {
    if (!reader.next(words)) reader.fail(MeshError::Kind::Unreadable, "file ends after " + std::to_string(v) + " of " + std::to_string(n) + " vertex lines");
    long long id = 0;
    if (words.size() != 2 || words[0] != "v" || !parse(words[1], id))
      reader.fail(MeshError::Kind::Unreadable, "expected \"v <input vertex id, or -1 for a vertex inserted by refinement>\" (vertex " + std::to_string(v) + ")");
    if (id < -1 || id >= file.input_vertices)
      reader.fail(MeshError::Kind::Defective, "vertex " + std::to_string(v) + ": input vertex " + std::to_string(id) +
                                                  " out of range (" + std::to_string(file.input_vertices) + ")");
    if (!used[static_cast<std::size_t>(v)])
      reader.fail(MeshError::Kind::Defective, "vertex " + std::to_string(v) + " is used by no face");
    file.to_input[static_cast<std::size_t>(v)] = static_cast<Index>(id);
  }
  if (reader.next(words)) reader.fail(MeshError::Kind::Unreadable, "unexpected content after the last vertex line");
  // Each input vertex at most once (sorted, not a table of input_vertices entries: that count is
  // not bounded by the file's size).
  std::vector<Index> order(file.to_input.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<Index>(i);
  std::sort(order.begin(), order.end(), [&](Index a, Index b) {
    return file.to_input[a] < file.to_input[b] || (file.to_input[a] == file.to_input[b] && a < b);
  });
  for (std::size_t i = 1; i < order.size(); ++i)
    if (file.to_input[order[i]] != kInvalid && file.to_input[order[i]] == file.to_input[order[i - 1]])
      throw MeshError(MeshError::Kind::Defective, path,
                      "input vertex " + std::to_string(file.to_input[order[i]]) + " listed twice (vertices " +
                          std::to_string(order[i - 1]) + " and " + std::to_string(order[i]) + ")");
  return file;
}

IntrinsicTriangulation triangulation_of(const IntrinsicMeshFile& file, const std::string& path) {
  try {
    return file.twin.empty() ? IntrinsicTriangulation::from_lengths(file.F, file.L)
                             : IntrinsicTriangulation::from_glued_faces(file.F, file.L, file.twin);
  } catch (const std::invalid_argument& e) {
    std::string what = e.what();
    if (what.rfind("IntrinsicTriangulation: ", 0) == 0) what.erase(0, 24);
    throw MeshError(MeshError::Kind::Defective, path,
                    what + (file.twin.empty() ? " (a version-1 file glues faces by vertex pairs, which cannot describe "
                                                "self- or multi-edges: write it again with this version)"
                                              : ""));
  }
}

void write_intrinsic_mesh(const std::string& path, const CompactMesh& mesh, Index input_vertices,
                          const std::string& comment) {
  const std::vector<Index> twin = mesh.twin.empty() ? glue_by_vertex_pairs(mesh.F) : mesh.twin;
  if (twin.size() != static_cast<std::size_t>(3 * mesh.F.rows()))
    throw std::invalid_argument("write_intrinsic_mesh: the gluing must have 3 entries per face");
  std::ofstream out(path);
  if (!out) throw MeshError(MeshError::Kind::Unwritable, path, "cannot be opened for writing");
  out << "ICE-ILM 2\n";
  if (!comment.empty()) out << "# " << comment << "\n";
  out << "# f i j k l_ij l_jk l_ki t_ij t_jk t_ki (0-based vertices, edge lengths, twin sides 3*face+side or -1);"
         " v input_vertex_of_vertex (-1: inserted by refinement)\n"
      << "vertices " << mesh.to_input.size() << "\nfaces " << mesh.F.rows() << "\ninput_vertices " << input_vertices
      << '\n';
  const auto twin_text = [&](Eigen::Index side) {
    const Index t = twin[static_cast<std::size_t>(side)];
    return t == kInvalid ? std::string("-1") : std::to_string(t);
  };
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    out << "f " << mesh.F(f, 0) << ' ' << mesh.F(f, 1) << ' ' << mesh.F(f, 2) << ' ' << shortest(mesh.L(f, 0)) << ' '
        << shortest(mesh.L(f, 1)) << ' ' << shortest(mesh.L(f, 2)) << ' ' << twin_text(3 * f) << ' '
        << twin_text(3 * f + 1) << ' ' << twin_text(3 * f + 2) << '\n';
  for (Index v : mesh.to_input) out << "v " << v << '\n';
  out.flush();
  if (!out) throw MeshError(MeshError::Kind::Unwritable, path, "write failed");
}

}  // namespace ice
