#include "ice/mesh.h"

namespace ice {

FaceLengths face_lengths_from_positions(const Positions& V, const Faces& F) {
  FaceLengths lengths(F.rows(), 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      lengths(f, k) = edge_length(V, F(f, k), F(f, (k + 1) % 3));
  return lengths;
}

}  // namespace ice
