// ice-info: read a mesh, print its validation report (for humans or as JSON), optionally repair it and
// write the repaired mesh. An .ilm file (a coarse intrinsic mesh from ice-coarsen) gets the intrinsic
// summary instead: sizes, Euler characteristic, area, Gauss–Bonnet, angles, Delaunay edges.
//
// Exit codes: 0 clean (or repaired to clean), 1 unreadable input, 2 defective input (after repair, if
// asked), 3 output not written, 4 bad command line.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <optional>
#include <sstream>

#include "tool_main.h"
#include "ice/intrinsic_mesh_io.h"
#include "ice/mesh_io.h"
#include "ice/mesh_repair.h"
#include "ice/mesh_validation.h"
#include "app_common.h"

namespace ice_info_tool {

using app::kDefective;
using app::kNotWritten;
using app::kUnreadable;

constexpr std::size_t kComponentsShown = 10;

std::string yes_no(bool b) { return b ? "yes" : "no"; }

std::string vec3(const Eigen::Vector3d& v) {
  std::ostringstream s;
  s << std::setprecision(9) << '(' << v.x() << ", " << v.y() << ", " << v.z() << ')';
  return s.str();
}

void print_report(std::ostream& out, const ice::ValidationReport& r) {
  out << "  vertices " << r.n_vertices << ", faces " << r.n_faces << ", edges " << r.n_edges << '\n'
      << "  components " << r.components.size() << ", boundary loops " << r.n_boundary_loops
      << ", Euler characteristic " << r.euler_characteristic << ", genus "
      << (r.genus >= 0 ? std::to_string(r.genus) : std::string("n/a")) << '\n'
      << "  manifold " << yes_no(r.manifold()) << " (" << r.non_manifold_edges.count << " edges, "
      << r.non_manifold_vertices.count << " vertices non-manifold), orientable " << yes_no(r.orientable())
      << ", consistently oriented " << yes_no(r.inconsistent_edges.empty()) << '\n'
      << "  bounding box " << vec3(r.bbox_min) << " - " << vec3(r.bbox_max) << ", diagonal "
      << (r.bbox_max - r.bbox_min).norm() << '\n'
      << "  edge length min " << r.edge_length_min << ", mean " << r.edge_length_mean << ", max "
      << r.edge_length_max << '\n';
  if (!r.duplicate_positions.empty()) {
    out << "  info: " << r.duplicate_positions.count << " vertices repeat an earlier position (first:";
    for (int v : r.duplicate_positions.first) out << ' ' << v;
    out << ")\n";
  }
  if (r.components.size() > 1) {
    out << "  per component (V, F, boundary loops, chi, genus):\n";
    for (std::size_t i = 0; i < std::min(r.components.size(), kComponentsShown); ++i) {
      const auto& c = r.components[i];
      out << "    #" << i << ": " << c.n_vertices << ", " << c.n_faces << ", " << c.n_boundary_loops << ", "
          << c.euler_characteristic << ", " << (c.genus >= 0 ? std::to_string(c.genus) : std::string("n/a")) << '\n';
    }
    if (r.components.size() > kComponentsShown)
      out << "    ... " << r.components.size() - kComponentsShown << " more\n";
  }
  const auto defects = r.defects();
  if (defects.empty()) out << "  defects: none\n";
  for (const auto& d : defects) out << "  DEFECT: " << d << '\n';
}

// The summary of an .ilm file: what the format holds and what its intrinsic triangulation says.
int describe_intrinsic_mesh(const std::string& input, bool json) {
  ice::IntrinsicMeshFile file;
  try {
    file = ice::read_intrinsic_mesh(input);
  } catch (const ice::MeshError& e) {
    if (json) std::cout << nlohmann::json{{"file", input}, {"readable", false}, {"error", e.what()}}.dump(2) << '\n';
    std::cerr << "ice-info: " << e.what() << '\n';
    return e.kind() == ice::MeshError::Kind::Defective ? kDefective : kUnreadable;
  }
  std::optional<ice::IntrinsicTriangulation> T;
  std::string problem;
  try {
    T.emplace(ice::triangulation_of(file, input));
    problem = T->validate();
  } catch (const ice::MeshError& e) {
    problem = e.what();
  }
  nlohmann::json j;
  j["file"] = input;
  j["readable"] = true;
  j["format"] = "ilm";
  j["format_version"] = file.version;
  j["vertices"] = file.to_input.size();
  j["faces"] = file.F.rows();
  j["input_vertices"] = file.input_vertices;
  j["valid"] = problem.empty();
  if (!problem.empty()) j["problem"] = problem;
  if (T) {
    double smallest = ice::kPi, largest = 0;
    ice::Index non_delaunay = 0, boundary_edges = 0;
    for (ice::Index h = 0; h < T->num_halfedge_slots(); ++h) {
      if (!T->halfedge_alive(h)) continue;
      if (!T->is_exterior(h)) {
        const double angle = T->corner_angle(h);
        smallest = std::min(smallest, angle), largest = std::max(largest, angle);
      }
      if (h % 2 == 0 && T->is_boundary_edge(h)) ++boundary_edges;
      if (h % 2 == 0 && !T->is_delaunay(h)) ++non_delaunay;
    }
    j["edges"] = T->num_edges();
    j["boundary_edges"] = boundary_edges;
    j["euler_characteristic"] = T->euler_characteristic();
    j["total_area"] = T->total_area();
    j["total_curvature"] = T->total_curvature();
    j["gauss_bonnet_2_pi_chi"] = 2 * ice::kPi * T->euler_characteristic();
    j["min_angle_degrees"] = smallest * 180 / ice::kPi;
    j["max_angle_degrees"] = largest * 180 / ice::kPi;
    j["non_delaunay_edges"] = non_delaunay;
  }
  if (json) {
    std::cout << j.dump(2) << '\n';
  } else {
    std::cout << input << " (ICE intrinsic mesh: faces and edge lengths; no positions)\n"
              << "  vertices " << j["vertices"] << ", faces " << j["faces"] << ", made from a mesh of "
              << file.input_vertices << " vertices\n";
    if (T)
      std::cout << std::setprecision(6) << "  edges " << T->num_edges() << " (" << j["boundary_edges"]
                << " on the boundary), Euler characteristic " << T->euler_characteristic() << "\n  area "
                << T->total_area() << ", total curvature " << T->total_curvature() << " (2πχ = "
                << j["gauss_bonnet_2_pi_chi"].get<double>() << ")\n  angles " << j["min_angle_degrees"].get<double>()
                << "° to " << j["max_angle_degrees"].get<double>() << "°, " << j["non_delaunay_edges"]
                << " non-Delaunay edges\n";
    std::cout << "status: " << (problem.empty() ? "valid" : "INVALID: " + problem) << '\n';
  }
  return problem.empty() ? app::kOk : kDefective;
}

int run(const std::string& input, const std::string& output, bool json, bool repair, bool weld, bool force);

}  // namespace ice_info_tool

int ice_info_tool::main(int argc, char** argv) {
  CLI::App app{"Read a triangle mesh, validate it for ICE and print the report."};
  std::string input, output;
  bool json = false, repair = false, weld = false, force = false;
  app.add_option("mesh", input, "Mesh file (.obj, .off, .ply, .stl), or an intrinsic mesh (.ilm)")->required();
  app.add_flag("--json", json, "Print the report as JSON");
  app.add_flag("--repair", repair, "Apply the safe repairs (see ice/mesh_repair.h) and report them");
  app.add_flag("--weld", weld, "With --repair: also weld vertices with exactly equal positions");
  app.add_option("--output,-o", output, "Write the (repaired) mesh here if it is clean (.obj/.off/.ply/.stl)");
  app.add_flag("--force", force, "Overwrite the output file if it exists");
  if (const int status = app::parse_command_line(app, argc, argv); status >= 0) return status;
  return app::run_tool("ice-info", [&] { return run(input, output, json, repair, weld, force); });
}

namespace ice_info_tool {

// The tool after the command line: read, validate, repair, report, write. Exit statuses as in
// app_common.h (errors that reach run_tool are reported there).
int run(const std::string& input, const std::string& output, bool json, bool repair, bool weld, bool force) {
  if (weld && !repair) throw app::AppError(app::kUsage, "--weld needs --repair");
  if (input.size() > 4 && input.compare(input.size() - 4, 4, ".ilm") == 0) {
    if (repair || !output.empty())
      throw app::AppError(app::kUsage, "--repair and --output apply to extrinsic meshes, not to .ilm files");
    return describe_intrinsic_mesh(input, json);
  }
  if (!output.empty()) app::check_output(output, force, "--output");  // before any work, as every tool does
  const auto start = std::chrono::steady_clock::now();
  ice::MeshFile file;
  try {
    file = ice::read_mesh_file(input);
  } catch (const ice::MeshError& e) {
    if (json)
      std::cout << nlohmann::json{{"file", input}, {"readable", false}, {"error", e.what()}}.dump(2) << '\n';
    std::cerr << "ice-info: " << e.what() << '\n';
    return kUnreadable;
  }
  const ice::ValidationReport input_report = ice::validate_mesh(file.soup);
  const double read_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  ice::RepairResult repaired;
  if (repair) {
    ice::RepairOptions options;
    options.weld_duplicate_positions = weld;
    repaired = ice::repair_mesh(file.soup, options);
  }
  const ice::ValidationReport& final_report = repair ? repaired.report : input_report;
  const bool clean = final_report.clean() && !(repair ? repaired.soup : file.soup).polygons.empty();

  if (json) {
    nlohmann::json j;
    j["file"] = input;
    j["readable"] = true;
    j["format"] = file.format;
    j["exact_coordinates"] = file.exact_coordinates;
    j["reader_notes"] = file.notes;
    j["read_and_validate_seconds"] = read_seconds;
    j["report"] = ice::proxy::validation_json(input_report);
    if (repair) {
      j["repairs"] = repaired.log.summary();
      j["repaired_report"] = ice::proxy::validation_json(repaired.report);
    }
    j["clean"] = clean;
    std::cout << j.dump(2) << '\n';
  } else {
    std::cout << input << " (" << file.format << ", "
              << (file.exact_coordinates ? "exact coordinates" : "float32 coordinates") << ", read and validated in "
              << std::fixed << std::setprecision(2) << read_seconds << " s)\n"
              << std::defaultfloat << std::setprecision(6);
    for (const auto& note : file.notes) std::cout << "  note: " << note << '\n';
    print_report(std::cout, input_report);
    if (repair) {
      const auto lines = repaired.log.summary();
      std::cout << "repair: " << (lines.empty() ? "nothing to do" : "") << '\n';
      for (const auto& line : lines) std::cout << "  " << line << '\n';
      std::cout << "after repair:\n";
      print_report(std::cout, repaired.report);
    }
    std::cout << "status: " << (clean ? "clean" : "DEFECTIVE") << '\n';
  }

  if (!clean) {
    // What the solvers would do with it: refuse it, or take it on its tufted cover (a point cloud, or
    // defects of sheets only: non-manifold edges, non-orientable or inconsistently oriented parts).
    if (file.soup.polygons.empty() && file.soup.V.rows() > 0)  // (its repair drops every point)
      std::cerr << "ice-info: " << input << ": a point cloud of " << file.soup.V.rows()
                << " points (no faces): the solvers take it with --nonmanifold tufted\n";
    else
      std::cerr << "ice-info: " << input << ": defective" << (repair ? " even after repair" : " (try --repair)")
                << (final_report.clean_but_for_sheets() ? "; the solvers take it on its tufted cover with --nonmanifold tufted"
                                                        : ", ICE would refuse it")
                << '\n';
    if (!output.empty()) std::cerr << "ice-info: not writing " << output << '\n';
    return kDefective;
  }
  if (!output.empty()) {  // a write error reaches run_tool: exit 3 naming the file
    ice::TriangleMesh mesh;
    const ice::PolygonSoup& soup = repair ? repaired.soup : file.soup;
    mesh.V = soup.V;
    mesh.F.resize(static_cast<Eigen::Index>(soup.polygons.size()), 3);
    for (std::size_t f = 0; f < soup.polygons.size(); ++f)
      for (int k = 0; k < 3; ++k) mesh.F(f, k) = soup.polygons[f][k];
    ice::write_mesh(output, mesh, {force, false});
    if (!json) std::cout << "wrote " << output << '\n';
  }
  return app::kOk;
}

}  // namespace ice_info_tool
