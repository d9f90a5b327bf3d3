#include "ice/triangulation_history.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace ice {

void TriangulationHistory::append(TriangulationHistory&& shard) {
  face_slots = std::max(face_slots, shard.face_slots);
  for (Chunk& chunk : shard.chunks)
    if (!chunk.records.empty()) chunks.push_back(std::move(chunk));
  shard.chunks.clear();
}

namespace {

using Triangle = std::array<Vec2, 3>;
constexpr int kMaxRecordFaces = 8;  // the largest record: an edge split, 2 old and 4 new faces

// Calls visit(record, its points, its faces) for every record, first to last (forward) or last to first.
template <class Visit>
void for_each_record(const TriangulationHistory& history, bool forward, Visit&& visit) {
  const std::size_t chunks = history.chunks.size();
  for (std::size_t c = 0; c < chunks; ++c) {
    const TriangulationHistory::Chunk& chunk = history.chunks[forward ? c : chunks - 1 - c];
    if (forward) {
      std::size_t point = 0, face = 0;
      for (const TriangulationHistory::Record& record : chunk.records) {
        visit(record, chunk.points.data() + point, chunk.faces.data() + face);
        point += record.num_points;
        face += static_cast<std::size_t>(record.old_faces) + record.new_faces;
      }
    } else {
      std::size_t point = chunk.points.size(), face = chunk.faces.size();
      for (auto record = chunk.records.rbegin(); record != chunk.records.rend(); ++record) {
        point -= record->num_points;
        face -= static_cast<std::size_t>(record->old_faces) + record->new_faces;
        visit(*record, chunk.points.data() + point, chunk.faces.data() + face);
      }
    }
  }
}

Triangle corners(const TriangulationHistory::Face& face, const Vec2* points) {
  return {points[face.corner[0]], points[face.corner[1]], points[face.corner[2]]};
}

Vec2 position(const Triangle& t, const std::array<double, 3>& b) { return t[0] * b[0] + t[1] * b[1] + t[2] * b[2]; }

// |v| by a square root (Vec2::norm's hypot guards against overflow that lengths of a layout never
// reach, at several times the cost: most of the pull-back's arithmetic).
double length_of(Vec2 v) { return std::sqrt(v.x * v.x + v.y * v.y); }

// Of `count` triangles of one layout, the one x lies deepest in by its smallest barycentric
// coordinate (the one holding it; at round-off outside all, the nearest), and x's coordinates there.
int deepest(const Triangle* triangles, int count, Vec2 x, std::array<double, 3>& bary) {
  int best = 0;
  double deepest_coordinate = -1e300;
  for (int j = 0; j < count; ++j) {
    const Triangle& t = triangles[j];
    const std::array<double, 3> b = barycentric(x, t[0], t[1], t[2]);
    const double d = std::min({b[0], b[1], b[2]});
    if (d > deepest_coordinate) deepest_coordinate = d, best = j, bary = b;
  }
  return best;
}

// The parameters t ∈ [lo, hi] ⊂ [0, 1] for which a + t (b − a) lies in t's triangle, its sides
// moved out by `tolerance`; false when there are none. *exit: the side (corner k to k + 1) that
// ends the interval before b, or −1.
bool clip(const Triangle& t, Vec2 a, Vec2 b, double tolerance, double& lo, double& hi, int* exit) {
  lo = 0, hi = 1;
  *exit = -1;
  for (int k = 0; k < 3; ++k) {
    const Vec2 side = t[(k + 1) % 3] - t[k];
    const double length = length_of(side);
    if (length == 0) continue;
    const double da = orient2d(t[k], t[(k + 1) % 3], a) / length + tolerance;
    const double db = orient2d(t[k], t[(k + 1) % 3], b) / length + tolerance;
    if (da < 0 && db < 0) return false;
    if (da >= 0 && db >= 0) continue;
    const double cut = da / (da - db);
    if (da < 0) {
      lo = std::max(lo, cut);
    } else if (cut < hi) {
      hi = cut;
      *exit = k;
    }
  }
  return lo <= hi;
}

// Where a → b crosses the line of side k of t: the fraction along the side from corner k, in [0, 1].
double side_fraction(const Triangle& t, int k, Vec2 a, Vec2 b) {
  const Vec2 p = t[k], q = t[(k + 1) % 3];
  const double da = orient2d(p, q, a), db = orient2d(p, q, b);
  const Vec2 x = da == db ? a : a + (b - a) * (da / (da - db));
  const Vec2 side = q - p;
  const double squared = side.x * side.x + side.y * side.y;
  return std::clamp(((x.x - p.x) * side.x + (x.y - p.y) * side.y) / squared, 0.0, 1.0);
}

std::array<double, 3> normalised(std::array<double, 3> b) {
  const double sum = b[0] + b[1] + b[2];
  for (double& c : b) c /= sum;
  return b;
}

// A flattening's map of one face's coordinates b: those at the flattened vertex's corners
// (face.corner 1) multiplied by `weight` (or, undoing it, divided), then renormalised.
std::array<double, 3> rescaled(const TriangulationHistory::Face& face, std::array<double, 3> b, double weight, bool undo) {
  for (int k = 0; k < 3; ++k)
    if (face.corner[k]) b[k] = undo ? b[k] / weight : b[k] * weight;
  return normalised(b);
}

// Round-off tolerance of a record's layout: its points' extent times 1e-10.
double layout_tolerance(const Vec2* points, int count) {
  double extent = 0;
  for (int i = 1; i < count; ++i) {
    const Vec2 d = points[i] - points[0];
    extent = std::max(extent, d.x * d.x + d.y * d.y);
  }
  return 1e-10 * std::sqrt(extent);
}

}  // namespace

std::vector<std::vector<FaceSegment>> pull_back(const TriangulationHistory& history,
                                                std::vector<std::vector<FaceSegment>> curves) {
  const Index slots = std::max(history.initial_faces, history.face_slots);
  // The segments in a pool, each curve a linked list through it (next), each face slot one through
  // the segments that lie in it now (next_in_face from first_in_face).
  struct Piece {
    FaceSegment segment;
    int next = -1, next_in_face = -1;
  };
  std::vector<Piece> pool;
  std::vector<int> first(curves.size(), -1);
  std::vector<int> first_in_face(static_cast<std::size_t>(slots), -1);
  const auto file = [&](int id) {
    int& head = first_in_face[static_cast<std::size_t>(pool[static_cast<std::size_t>(id)].segment.face)];
    pool[static_cast<std::size_t>(id)].next_in_face = head;
    head = id;
  };
  for (std::size_t c = 0; c < curves.size(); ++c) {
    int previous = -1;
    for (const FaceSegment& segment : curves[c]) {
      if (segment.face < 0 || segment.face >= slots)
        throw std::invalid_argument("pull_back: a curve lies on face slot " + std::to_string(segment.face) +
                                    ", which the triangulation does not have");
      const int id = static_cast<int>(pool.size());
      pool.push_back({segment, -1, -1});
      (previous < 0 ? first[c] : pool[static_cast<std::size_t>(previous)].next) = id;
      previous = id;
      file(id);
    }
  }

  std::vector<std::pair<int, int>> moved;  // (segment, new face of the record it lies in)
  for_each_record(history, false, [&](const TriangulationHistory::Record& record, const Vec2* points,
                                      const TriangulationHistory::Face* faces) {
    if (record.flattening) {  // undo the rescaling at the vertex's corners, face by face
      const double weight = points[0].x;
      for (int i = 0; i < record.old_faces; ++i)
        for (int id = first_in_face[static_cast<std::size_t>(faces[i].slot)]; id >= 0;
             id = pool[static_cast<std::size_t>(id)].next_in_face) {
          FaceSegment& s = pool[static_cast<std::size_t>(id)].segment;
          s.from = rescaled(faces[i], s.from, weight, true);
          s.to = rescaled(faces[i], s.to, weight, true);
        }
      return;
    }
    const TriangulationHistory::Face* old_faces = faces;
    const TriangulationHistory::Face* new_faces = faces + record.old_faces;
    moved.clear();
    for (int j = 0; j < record.new_faces; ++j) {
      int& head = first_in_face[static_cast<std::size_t>(new_faces[j].slot)];
      for (int id = head; id >= 0; id = pool[static_cast<std::size_t>(id)].next_in_face) moved.emplace_back(id, j);
      head = -1;
    }
    if (moved.empty()) return;
    const double tolerance = layout_tolerance(points, record.num_points);
    std::array<Triangle, kMaxRecordFaces> before{};
    for (int i = 0; i < record.old_faces; ++i) before[i] = corners(old_faces[i], points);
    for (const auto& [id, j] : moved) {
      const FaceSegment segment = pool[static_cast<std::size_t>(id)].segment;
      const Triangle now = corners(new_faces[j], points);
      const Vec2 a = position(now, segment.from), b = position(now, segment.to);
      const double length = length_of(b - a);
      // The pieces of a → b in the old faces, in order along it: (face, t0, t1), and the side of
      // the face it leaves through (−1: its end, or a corner) with the fraction along that side, so
      // that the point where one piece ends and the next begins is the same point of their common
      // side in both faces (a crossing computed from the tolerance band would drift along a side
      // the segment meets at a grazing angle).
      struct Cut {
        int face;
        double t0, t1;
        int exit;
        double fraction;
      };
      std::array<Cut, 2 * kMaxRecordFaces> cuts{};
      int count = 0;
      if (length > tolerance) {
        std::array<double, kMaxRecordFaces> lo{}, hi{};
        std::array<int, kMaxRecordFaces> exit{};
        std::array<bool, kMaxRecordFaces> meets{};
        for (int i = 0; i < record.old_faces; ++i) meets[i] = clip(before[i], a, b, tolerance, lo[i], hi[i], &exit[i]);
        const double slack = tolerance / length + 1e-12;
        for (double at = 0; at < 1 && count < static_cast<int>(cuts.size());) {
          int best = -1;
          double reach = at;
          for (int i = 0; i < record.old_faces; ++i)
            if (meets[i] && lo[i] <= at + slack && hi[i] > reach) best = i, reach = hi[i];
          if (best < 0) {  // a gap of round-off: on into the face that starts next
            for (int i = 0; i < record.old_faces; ++i)
              if (meets[i] && lo[i] > at && (best < 0 || lo[i] < lo[best])) best = i;
            if (best < 0) break;
            reach = hi[best];
          }
          if (reach >= 1 - slack) reach = 1;
          const int side = reach < 1 ? exit[best] : -1;
          cuts[count++] = {best, at, reach, side, side >= 0 ? side_fraction(before[best], side, a, b) : 0.0};
          at = reach;
        }
      }
      if (count == 0) {  // a point (or nothing found): the face that holds its middle deepest
        std::array<double, 3> unused;
        cuts[count++] = {deepest(before.data(), record.old_faces, (a + b) * 0.5, unused), 0, 1, -1, 0.0};
      }
      cuts[count - 1].t1 = 1;
      cuts[count - 1].exit = -1;
      // The first piece takes the segment's place in its curve, the others follow it.
      const int after = pool[static_cast<std::size_t>(id)].next;
      int previous = -1;
      for (int c = 0; c < count; ++c) {
        const Cut& cut = cuts[c];
        const Triangle& t = before[cut.face];
        const auto point_at = [&](double s) { return s == 0 ? a : s == 1 ? b : a + (b - a) * s; };
        FaceSegment piece;
        piece.face = old_faces[cut.face].slot;
        piece.from = clamp_barycentric(barycentric(point_at(cut.t0), t[0], t[1], t[2]));
        piece.to = clamp_barycentric(barycentric(point_at(cut.t1), t[0], t[1], t[2]));
        if (cut.exit >= 0) {  // ends on its side `exit`
          piece.to = {0, 0, 0};
          piece.to[cut.exit] = 1 - cut.fraction;
          piece.to[(cut.exit + 1) % 3] = cut.fraction;
        }
        if (c > 0 && cuts[c - 1].exit >= 0) {  // begins where the last piece left its face: on the same side here
          const TriangulationHistory::Face& last = old_faces[cuts[c - 1].face];
          const int from_point = last.corner[cuts[c - 1].exit], to_point = last.corner[(cuts[c - 1].exit + 1) % 3];
          const TriangulationHistory::Face& here = old_faces[cut.face];
          for (int k = 0; k < 3; ++k)
            if (here.corner[k] == to_point && here.corner[(k + 1) % 3] == from_point) {
              piece.from = {0, 0, 0};
              piece.from[k] = cuts[c - 1].fraction;
              piece.from[(k + 1) % 3] = 1 - cuts[c - 1].fraction;
            }
        }
        piece.from_param = segment.from_param + cut.t0 * (segment.to_param - segment.from_param);
        piece.to_param = cut.t1 == 1 ? segment.to_param : segment.from_param + cut.t1 * (segment.to_param - segment.from_param);
        int piece_id = id;
        if (c > 0) {
          piece_id = static_cast<int>(pool.size());
          pool.push_back({});
          pool[static_cast<std::size_t>(previous)].next = piece_id;
        }
        pool[static_cast<std::size_t>(piece_id)].segment = piece;
        pool[static_cast<std::size_t>(piece_id)].next = after;
        file(piece_id);
        previous = piece_id;
      }
    }
  });

  std::vector<std::vector<FaceSegment>> result(curves.size());
  for (std::size_t c = 0; c < curves.size(); ++c)
    for (int id = first[c]; id >= 0; id = pool[static_cast<std::size_t>(id)].next)
      result[c].push_back(pool[static_cast<std::size_t>(id)].segment);
  return result;
}

std::vector<FacePoint> push_forward(const TriangulationHistory& history, std::vector<FacePoint> points) {
  const Index slots = std::max(history.initial_faces, history.face_slots);
  // Each face slot's points, a linked list through next_in_face.
  std::vector<int> first_in_face(static_cast<std::size_t>(slots), -1), next_in_face(points.size(), -1);
  const auto file = [&](int p) {
    int& head = first_in_face[static_cast<std::size_t>(points[static_cast<std::size_t>(p)].face)];
    next_in_face[static_cast<std::size_t>(p)] = head;
    head = p;
  };
  for (std::size_t p = 0; p < points.size(); ++p) {
    if (points[p].face < 0 || points[p].face >= history.initial_faces)
      throw std::invalid_argument("push_forward: a point lies on face slot " + std::to_string(points[p].face) +
                                  ", not one of the " + std::to_string(history.initial_faces) + " initial faces");
    file(static_cast<int>(p));
  }
  std::vector<std::pair<int, Vec2>> moved;
  for_each_record(history, true, [&](const TriangulationHistory::Record& record, const Vec2* layout,
                                     const TriangulationHistory::Face* faces) {
    if (record.flattening) {
      const double weight = layout[0].x;
      for (int i = 0; i < record.old_faces; ++i)
        for (int p = first_in_face[static_cast<std::size_t>(faces[i].slot)]; p >= 0; p = next_in_face[static_cast<std::size_t>(p)]) {
          std::array<double, 3>& b = points[static_cast<std::size_t>(p)].bary;
          b = rescaled(faces[i], b, weight, false);
        }
      return;
    }
    moved.clear();
    for (int i = 0; i < record.old_faces; ++i) {
      int& head = first_in_face[static_cast<std::size_t>(faces[i].slot)];
      const Triangle t = corners(faces[i], layout);
      for (int p = head; p >= 0; p = next_in_face[static_cast<std::size_t>(p)])
        moved.emplace_back(p, position(t, points[static_cast<std::size_t>(p)].bary));
      head = -1;
    }
    const TriangulationHistory::Face* new_faces = faces + record.old_faces;
    std::array<Triangle, kMaxRecordFaces> after{};
    for (int j = 0; j < record.new_faces; ++j) after[j] = corners(new_faces[j], layout);
    for (const auto& [p, x] : moved) {  // into the new face where it lies deepest
      std::array<double, 3> bary{};
      const int best = deepest(after.data(), record.new_faces, x, bary);
      points[static_cast<std::size_t>(p)] = {new_faces[best].slot, clamp_barycentric(bary)};
      file(p);
    }
  });
  return points;
}

}  // namespace ice
