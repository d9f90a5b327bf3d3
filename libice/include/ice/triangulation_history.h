#pragma once
/// \file triangulation_history.h
/// The local operations an intrinsic triangulation went through, recorded (on request:
/// IntrinsicTriangulation::record_history) so that curves drawn on its current faces can be pulled
/// back to the faces it was built from, and points of those faces pushed forward to the current ones.
///
/// Why this is exact: every operation that moves the tracked points is, on the faces it touches,
/// either a retriangulation of one planar region (a flip; a vertex removal, whose flattened star is
/// laid out flat and merged into one or two faces; an insertion; an edge split) — an affine map on
/// each piece old face ∩ new face — or a flattening, which rescales the barycentric coordinates at
/// one vertex's corners and renormalises them inside each face of its star — a projective map of each
/// face onto itself. Both map straight segments to straight segments (the first after splitting
/// them where they cross the old faces' sides), so a curve that is straight in each current face is,
/// pulled back through the records, a polyline straight in each initial face: the preimage under the
/// fine-to-coarse map itself, not an approximation of it. Coarse edges pulled back this way run
/// between their end vertices, stay on the input surface and meet only at shared ends (the map is a
/// bijection), up to round-off (ice/coarse_tracing.h).
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "ice/mesh.h"
#include "ice/triangle_geometry.h"

namespace ice {

struct TriangulationHistory {
  /// One operation. A retriangulation replaces `old_faces` by `new_faces`, all laid out in one plane
  /// through `num_points` points; each face lists its corners' points in its own corner order (the
  /// corners of its halfedge, next, next·next) at that time. A flattening lists the faces of the
  /// star (old and new are the same slots) with corner entries 1 at the flattened vertex, whose
  /// coordinates were multiplied by a weight before renormalising: its one point is (weight, 0).
  /// A record's points and faces follow the previous record's in its chunk.
  struct Record {
    std::uint8_t num_points = 0, old_faces = 0, new_faces = 0;
    bool flattening = false;
  };
  struct Face {
    Index slot = kInvalid;
    std::array<std::uint8_t, 3> corner{0, 0, 0};
  };
  /// Records in order, with their points and faces; chunks keep appends and growth from copying.
  struct Chunk {
    std::vector<Record> records;
    std::vector<Vec2> points;
    std::vector<Face> faces;
  };
  std::vector<Chunk> chunks;
  /// Face slots of the triangulation when recording started: the initial faces are slots below it.
  Index initial_faces = 0;
  /// One past the largest face slot any record names.
  Index face_slots = 0;

  std::size_t num_records() const {
    std::size_t count = 0;
    for (const Chunk& chunk : chunks) count += chunk.records.size();
    return count;
  }
  std::size_t memory_bytes() const {
    std::size_t bytes = chunks.capacity() * sizeof(Chunk);
    for (const Chunk& chunk : chunks)
      bytes += chunk.records.capacity() * sizeof(Record) + chunk.points.capacity() * sizeof(Vec2) +
               chunk.faces.capacity() * sizeof(Face);
    return bytes;
  }
  /// The chunk new records go to (a new one when the last holds kChunkRecords).
  Chunk& writable() {
    if (chunks.empty() || chunks.back().records.size() >= kChunkRecords) chunks.emplace_back();
    return chunks.back();
  }
  /// Appends the records of `shard` (operations on faces disjoint from those of the records since
  /// the last append: a region coarsened on another thread) after this history's own, moving them.
  void append(TriangulationHistory&& shard);
  static constexpr std::size_t kChunkRecords = std::size_t{1} << 20;
};

/// A straight piece of a curve inside one face: barycentric coordinates of its ends w.r.t. the
/// face's corners (in the face's corner order), and the positions of its ends along the curve.
struct FaceSegment {
  Index face = kInvalid;
  std::array<double, 3> from{0, 0, 0}, to{0, 0, 0};
  double from_param = 0, to_param = 0;
};

/// Pulls curves back through every record of `history`, last first: each curve is a chain of
/// FaceSegments on the current faces, joined end to end; the result holds each as a chain on the
/// initial faces (slots < history.initial_faces), split where it crosses their sides (positions
/// along the curve interpolated linearly in each straight piece). Preconditions: the curves' faces
/// are live slots of the triangulation whose history this is; std::invalid_argument when a face
/// slot is out of the history's range.
std::vector<std::vector<FaceSegment>> pull_back(const TriangulationHistory& history,
                                                std::vector<std::vector<FaceSegment>> curves);

/// A point of a face: its slot and barycentric coordinates.
struct FacePoint {
  Index face = kInvalid;
  std::array<double, 3> bary{0, 0, 0};
};

/// Pushes points of the initial faces forward through every record, first first: where each lies in
/// the current faces (the tracked points' own update, for points that are not input vertices).
std::vector<FacePoint> push_forward(const TriangulationHistory& history, std::vector<FacePoint> points);

}  // namespace ice
