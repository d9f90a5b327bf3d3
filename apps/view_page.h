#pragma once
// The interactive 3D page of the tools and of ice-report: the input mesh coloured by per-vertex
// fields (solutions, errors, patch labels) and each coarsening method's coarse edges traced on it,
// in a page that opens from disk, offline (three.js and the viewer copied beside it).
//
//   app::ViewMesh mesh = app::view_mesh("bear", input, 200000);   // the display mesh
//   mesh.fields.push_back(app::view_field(mesh, "solution", "poisson", "solution", "", u));
//   app::ViewMesh::methods: {"ICE", coarse vertices, app::traced_segments(input, tracing), errors}
//   app::write_view_page("bear.html", "ICE on bear", {mesh}, "", force);
//
// app_common.h's write_result_page makes the page of one tool run (--html).
//
// Layout written: PAGE.html and PAGE_files/ (three.js, viewer.js, viewer.css, mesh-K.js). The data
// scripts call ICE_VIEWER.register(...) with base64 little-endian Float32/Uint32 arrays
// (apps/viewer/viewer.js states the format).
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ice/coarse_space.h"
#include "ice/coarse_tracing.h"
#include "ice/mesh.h"

namespace app {

struct ViewField {
  std::string name;     // unique within a mesh
  std::string problem;  // "poisson", "heat", "geodesic", or "" (labels)
  std::string kind;     // "solution", "error", "label"
  std::string method;   // "" = common to every method (the fine solution)
  std::vector<float> values;  // one per display vertex
};

struct ViewMethod {
  std::string name;     // "ICE", "QEM"
  bool ok = true;
  std::string message;  // why it failed
  long long coarse_vertices = 0;
  std::vector<float> edges;  // 6 floats a segment, on the input surface
  std::map<std::string, double> errors;  // problem -> relative error (fraction)
};

struct ViewMesh {
  std::string name;
  long long input_vertices = 0, input_faces = 0;
  ice::Positions V;  // display mesh
  ice::Faces F;
  bool decimated = false;
  bool points = false;  // a point cloud: the page draws the display vertices as points, not the faces
  // Display vertex -> input vertex (identity when not decimated): fields given per input vertex are
  // sampled through it.
  std::vector<ice::Index> input_vertex;
  std::vector<ViewField> fields;
  std::vector<ViewMethod> methods;
};

/// Display meshes above this many vertices are an ICE coarsening of the input: with base64 float32
/// buffers the page of a 1.66M-vertex input is then ready in 5 s in headless Chromium with software
/// WebGL (docs/measurements.md, "The 3D page and the output files").
constexpr long long kDisplayVertices = 200000;

/// The display mesh of an input: the input itself up to `max_vertices`, else an ICE coarsening to
/// that many vertices drawn with its surviving vertices' positions (their values are the input's at
/// those vertices: no resampling).
ViewMesh view_mesh(const std::string& name, const ice::TriangleMesh& input, long long max_vertices);

/// A per-input-vertex field sampled on the display mesh.
ViewField view_field(const ViewMesh& mesh, std::string name, std::string problem, std::string kind, std::string method,
                     const Eigen::VectorXd& input_values);

/// The traced coarse edges as segments (untraced edges are left out; their count is in `message`).
std::vector<float> traced_segments(const ice::TriangleMesh& input, const ice::CoarseTracing& tracing);

/// A coarse space as a page's method: its coarse edges — with `tracing` (ICE: ice::trace_coarse_mesh
/// of this space) the traced ones on the input surface, otherwise (QEM, an extrinsic mesh) straight
/// between its vertices' positions — and a note on what is drawn.
ViewMethod view_method(const std::string& name, const ice::TriangleMesh& input, const ice::CoarseSpace& space,
                       const ice::CoarseTracing* tracing);

/// The patch labels of a tracing as a per-input-vertex field (CoarseTracing::vertex_patch).
Eigen::VectorXd patch_values(const ice::CoarseTracing& tracing);

/// What write_view_page would refuse, checked before any work (AppError): PAGE.html or PAGE_files/
/// existing without `force`, PAGE's directory missing, the viewer's files not found.
void check_view_page(const std::string& page, bool force, const std::string& option = "--html");

/// Writes PAGE.html and PAGE_files/. Refuses to replace an existing page without `force`
/// (AppError kNotWritten); throws AppError when the viewer's assets are missing (run
/// `npm ci --prefix apps/viewer`, which scripts/setup.sh does).
void write_view_page(const std::string& page, const std::string& title, const std::vector<ViewMesh>& meshes,
                     const std::string& plots_html, bool force);

}  // namespace app
