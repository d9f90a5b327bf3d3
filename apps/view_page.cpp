#include "view_page.h"

#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "command_line.h"
#include "ice/coarse_space.h"

namespace app {
namespace fs = std::filesystem;

namespace {

// Standard base64 (RFC 4648, padded, no line breaks) of raw bytes: what the viewer's atob() reads.
std::string base64(const void* data, std::size_t size) {
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  const auto* bytes = static_cast<const unsigned char*>(data);
  std::string out;
  out.reserve((size + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 2 < size; i += 3) {
    const std::uint32_t word = (bytes[i] << 16) | (bytes[i + 1] << 8) | bytes[i + 2];
    for (int shift = 18; shift >= 0; shift -= 6) out += kAlphabet[(word >> shift) & 63];
  }
  if (i < size) {
    const std::uint32_t word = (bytes[i] << 16) | (i + 1 < size ? bytes[i + 1] << 8 : 0);
    out += kAlphabet[(word >> 18) & 63];
    out += kAlphabet[(word >> 12) & 63];
    out += i + 1 < size ? kAlphabet[(word >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

template <class T>
std::string base64_of(const std::vector<T>& values) {
  return base64(values.data(), values.size() * sizeof(T));
}

// A file name as one URL path segment (the page names its assets' folder relatively): bytes other
// than unreserved characters are percent-encoded, so spaces, '#', '?' and '%' in a page's name work.
std::string url_segment(const std::string& name) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  std::string out;
  for (const char c : name) {
    const auto byte = static_cast<unsigned char>(c);
    if (std::isalnum(byte) || c == '-' || c == '_' || c == '.' || c == '~') {
      out += c;
    } else {
      out += '%';
      out += kHex[byte >> 4];
      out += kHex[byte & 15];
    }
  }
  return out;
}

std::string html_escape(const std::string& text) {
  std::string out;
  for (const char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

// Where the viewer's files are: $ICE_VIEWER_DIR, the source tree's apps/viewer (three from its
// node_modules, installed there by `npm ci`; first, so a build never copies an older installed
// viewer), or the installed share/ice/viewer.
struct ViewerAssets {
  fs::path three, viewer_js, viewer_css, page_template;
};

ViewerAssets find_assets() {
  std::vector<fs::path> dirs;
  if (const char* env = std::getenv("ICE_VIEWER_DIR"); env && *env) dirs.emplace_back(env);
  dirs.emplace_back(ICE_VIEWER_SOURCE_DIR);
  dirs.emplace_back(ICE_VIEWER_INSTALL_DIR);
  for (const fs::path& dir : dirs) {
    ViewerAssets assets{dir / "three.js", dir / "viewer.js", dir / "viewer.css", dir / "page_template.html"};
    if (!fs::is_regular_file(assets.three)) assets.three = dir / "node_modules" / "three" / "build" / "three.cjs";
    if (fs::is_regular_file(assets.three) && fs::is_regular_file(assets.viewer_js) && fs::is_regular_file(assets.page_template))
      return assets;
  }
  throw AppError(kNotWritten, "the 3D page needs three.js and the viewer's files, found in none of $ICE_VIEWER_DIR, " +
                                  std::string(ICE_VIEWER_SOURCE_DIR) + ", " + ICE_VIEWER_INSTALL_DIR +
                                  " (run `npm ci --prefix apps/viewer`, which scripts/setup.sh does)");
}

std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

void replace_all(std::string& text, const std::string& from, const std::string& to) {
  for (std::size_t at = 0; (at = text.find(from, at)) != std::string::npos; at += to.size()) text.replace(at, from.size(), to);
}

// The points' diameter for a point cloud's page: the mean length of its display edges (its points'
// spacing), so that neighbouring points touch and the coarse edges still show between them.
double point_size(const ViewMesh& mesh) {
  double total = 0;
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) total += (mesh.V.row(mesh.F(f, k)) - mesh.V.row(mesh.F(f, (k + 1) % 3))).norm();
  return mesh.F.rows() > 0 ? total / static_cast<double>(3 * mesh.F.rows()) : 1.0;
}

nlohmann::json mesh_json(const ViewMesh& mesh) {
  std::vector<float> positions(static_cast<std::size_t>(3 * mesh.V.rows()));
  for (Eigen::Index v = 0; v < mesh.V.rows(); ++v)
    for (int c = 0; c < 3; ++c) positions[static_cast<std::size_t>(3 * v + c)] = static_cast<float>(mesh.V(v, c));
  std::vector<std::uint32_t> indices(static_cast<std::size_t>(3 * mesh.F.rows()));
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int c = 0; c < 3; ++c) indices[static_cast<std::size_t>(3 * f + c)] = static_cast<std::uint32_t>(mesh.F(f, c));
  nlohmann::json fields = nlohmann::json::array();
  for (const ViewField& field : mesh.fields) {
    float low = 0, high = 0;
    bool first = true;
    for (const float value : field.values)
      if (std::isfinite(value)) low = first ? value : std::min(low, value), high = first ? value : std::max(high, value), first = false;
    fields.push_back({{"name", field.name},
                      {"problem", field.problem.empty() ? nlohmann::json(nullptr) : nlohmann::json(field.problem)},
                      {"kind", field.kind},
                      {"method", field.method.empty() ? nlohmann::json(nullptr) : nlohmann::json(field.method)},
                      {"values", base64_of(field.values)},
                      {"min", field.kind == "error" ? 0.0f : low},
                      {"max", high}});
  }
  nlohmann::json methods = nlohmann::json::array();
  for (const ViewMethod& method : mesh.methods)
    methods.push_back({{"name", method.name},
                       {"status", method.ok ? "ok" : "failed"},
                       {"message", method.message},
                       {"coarse_vertices", method.coarse_vertices},
                       {"edges", base64_of(method.edges)},
                       {"segments", method.edges.size() / 6},
                       {"errors", method.errors}});
  return {{"name", mesh.name},
          {"input_vertices", mesh.input_vertices},
          {"input_faces", mesh.input_faces},
          {"display",
           {{"vertices", mesh.V.rows()},
            {"faces", mesh.F.rows()},
            {"decimated", mesh.decimated},
            {"points", mesh.points},
            {"point_size", mesh.points ? point_size(mesh) : 0.0},
            {"positions", base64_of(positions)},
            {"indices", base64_of(indices)}}},
          {"fields", fields},
          {"methods", methods}};
}

}  // namespace

ViewMesh view_mesh(const std::string& name, const ice::TriangleMesh& input, long long max_vertices) {
  ViewMesh mesh;
  mesh.name = name;
  mesh.input_vertices = input.V.rows();
  mesh.input_faces = input.F.rows();
  if (input.V.rows() <= max_vertices) {
    mesh.V = input.V;
    mesh.F = input.F;
    mesh.input_vertex.resize(static_cast<std::size_t>(input.V.rows()));
    for (ice::Index v = 0; v < input.V.rows(); ++v) mesh.input_vertex[v] = v;
    return mesh;
  }
  // A display mesh for a big input: its ICE coarsening with the survivors' positions (values at
  // display vertices are the input's own, so nothing is interpolated).
  ice::CoarseSpaceOptions options;
  options.coarsen.target_vertices = static_cast<ice::Index>(max_vertices);
  options.coarsen.threads = 0;
  options.nonmanifold = ice::NonmanifoldInput::tufted_cover;  // (a manifold: the same bits; a tool's covered mesh: drawn)
  const ice::CoarseSpace space = ice::build_coarse_space(input, options);
  mesh.V = ice::coarse_vertex_positions(input, space);
  mesh.F = space.mesh.F;
  mesh.input_vertex = space.mesh.to_input;
  mesh.decimated = true;
  return mesh;
}

ViewField view_field(const ViewMesh& mesh, std::string name, std::string problem, std::string kind, std::string method,
                     const Eigen::VectorXd& input_values) {
  ViewField field{std::move(name), std::move(problem), std::move(kind), std::move(method), {}};
  field.values.reserve(mesh.input_vertex.size());
  for (const ice::Index v : mesh.input_vertex) field.values.push_back(static_cast<float>(input_values[v]));
  return field;
}

std::vector<float> traced_segments(const ice::TriangleMesh& input, const ice::CoarseTracing& tracing) {
  std::vector<float> segments;
  for (const ice::TracedEdge& edge : tracing.edges) {
    if (edge.status != ice::TraceStatus::traced) continue;
    const ice::Positions points = ice::traced_polyline(input.V, input.F, edge);
    for (Eigen::Index i = 0; i + 1 < points.rows(); ++i)
      for (const Eigen::Index row : {i, i + 1})
        for (int c = 0; c < 3; ++c) segments.push_back(static_cast<float>(points(row, c)));
  }
  return segments;
}

Eigen::VectorXd patch_values(const ice::CoarseTracing& tracing) {
  Eigen::VectorXd patch(static_cast<Eigen::Index>(tracing.vertex_patch.size()));
  for (Eigen::Index v = 0; v < patch.size(); ++v) patch(v) = static_cast<double>(tracing.vertex_patch[static_cast<std::size_t>(v)]);
  return patch;
}

ViewMethod view_method(const std::string& name, const ice::TriangleMesh& input, const ice::CoarseSpace& space,
                       const ice::CoarseTracing* tracing) {
  ViewMethod method;
  method.name = name;
  method.coarse_vertices = space.mesh.num_vertices();
  if (tracing) {  // ICE: the edges as they are, on the surface
    method.edges = traced_segments(input, *tracing);
    if (tracing->failed > 0)
      method.message = std::to_string(tracing->failed) + " of " + std::to_string(tracing->edges.size()) +
                       " coarse edges could not be traced and are not drawn";
    return method;
  }
  // An extrinsic coarse mesh on its survivors' positions: its edges are the straight segments
  // between them (an interior edge from the side whose first vertex is the smaller).
  const ice::Positions positions = ice::coarse_vertex_positions(input, space);
  for (Eigen::Index f = 0; f < space.mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const ice::Index a = space.mesh.F(f, k), b = space.mesh.F(f, (k + 1) % 3);
      if (a > b) continue;
      for (const ice::Index v : {a, b})
        for (int c = 0; c < 3; ++c) method.edges.push_back(static_cast<float>(positions(v, c)));
    }
  method.message = "an extrinsic coarse mesh: its edges are drawn straight between its vertices";
  return method;
}

void check_view_page(const std::string& page, bool force, const std::string& option) {
  check_output(page, force, option);
  const fs::path page_path(page);
  const fs::path assets_dir = page_path.parent_path() / (page_path.stem().string() + "_files");
  if (fs::exists(assets_dir) && !force)
    throw AppError(kNotWritten, option + " " + page + ": " + assets_dir.string() + " exists already (--force overwrites)");
  find_assets();
}

void write_view_page(const std::string& page, const std::string& title, const std::vector<ViewMesh>& meshes,
                     const std::string& plots_html, bool force) {
  // The page's folder of assets is part of it: replaced only with --force too.
  check_view_page(page, force, "the page");
  const ViewerAssets assets = find_assets();
  const fs::path page_path(page);
  const std::string assets_name = page_path.stem().string() + "_files";
  const fs::path assets_dir = page_path.parent_path() / assets_name;
  const std::string assets_url = url_segment(assets_name);
  std::error_code ec;
  fs::create_directories(assets_dir, ec);
  if (ec) throw AppError(kNotWritten, "--html: cannot create " + assets_dir.string() + ": " + ec.message());
  for (const auto& [from, to] : {std::pair{assets.three, std::string("three.js")}, std::pair{assets.viewer_js, std::string("viewer.js")},
                                 std::pair{assets.viewer_css, std::string("viewer.css")}}) {
    fs::copy_file(from, assets_dir / to, fs::copy_options::overwrite_existing, ec);
    if (ec) throw AppError(kNotWritten, "--html: cannot copy " + from.string() + ": " + ec.message());
  }
  std::string scripts;
  for (std::size_t k = 0; k < meshes.size(); ++k) {
    const std::string name = "mesh-" + std::to_string(k) + ".js";
    std::ofstream out(assets_dir / name, std::ios::binary);
    out << "ICE_VIEWER.register(" << mesh_json(meshes[k]).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace)
        << ");\n";
    if (!out) throw AppError(kNotWritten, "--html: cannot write " + (assets_dir / name).string());
    scripts += "<script src=\"" + html_escape(assets_url) + "/" + name + "\"></script>\n";
  }
  std::string html = read_text(assets.page_template);
  replace_all(html, "@ASSETS@", html_escape(assets_url));
  replace_all(html, "@DATA_SCRIPTS@", scripts);
  replace_all(html, "@PLOTS@", plots_html);
  replace_all(html, "@TITLE@", html_escape(title));  // last: a title is text, never read as a placeholder
  std::ofstream out(page_path, std::ios::binary);
  out << html;
  if (!out) throw AppError(kNotWritten, "--html: cannot write " + page);
}

}  // namespace app
