#include "data_tools/geometry/segmentation_features.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/geodesic.h"
#include "data_tools/geometry/mesh.h"

namespace amt {
namespace {

// Distance from p to the segment [a, b] (a point when a == b).
float segment_distance(const Eigen::Vector3f& p, const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
  const Eigen::Vector3f ab = b - a;
  const float len2 = ab.squaredNorm();
  const float t = len2 > 0.0f ? std::clamp((p - a).dot(ab) / len2, 0.0f, 1.0f) : 0.0f;
  return (p - (a + t * ab)).norm();
}

}  // namespace

MatrixXfR segmentation_features(const MatrixX3f& V, const MatrixX3i& F, const MatrixX3f& joints,
                                const std::vector<int32_t>& parents) {
  validate_mesh(TriMesh{V, F}, "segmentation features");
  const Eigen::Index N = V.rows(), J = joints.rows();
  AMT_CHECK(static_cast<Eigen::Index>(parents.size()) == J, "segmentation features: parents: expected ", J,
            " (one per joint), found ", parents.size());
  for (Eigen::Index j = 0; j < J; ++j) {
    AMT_CHECK(joints.row(j).allFinite(), "segmentation features: joints: expected finite positions, found joint ", j,
              " at ", joints(j, 0), " ", joints(j, 1), " ", joints(j, 2));
    AMT_CHECK(parents[j] >= -1 && parents[j] < J, "segmentation features: parents: expected -1 or a joint in [0, ", J,
              "), found ", parents[j], " for joint ", j);
  }
  const float height = std::max(V.col(1).maxCoeff() - V.col(1).minCoeff(), 1e-6f);

  MatrixXfR out(N, kSegmentationFeatures);
  out.leftCols<3>() = vertex_normals(V, F);

  int count = 0;
  const std::vector<int32_t> label = connected_components(static_cast<int>(N), unique_edges(F), &count);
  std::vector<int32_t> size(static_cast<size_t>(count), 0);
  for (const int32_t l : label) ++size[static_cast<size_t>(l)];
  const int32_t largest = static_cast<int32_t>(std::max_element(size.begin(), size.end()) - size.begin());
  std::vector<int32_t> on_largest, off_largest;
  for (Eigen::Index i = 0; i < N; ++i) {
    out(i, 3) = static_cast<float>(size[static_cast<size_t>(label[i])]) / static_cast<float>(N);
    (label[i] == largest ? on_largest : off_largest).push_back(static_cast<int32_t>(i));
  }

  for (Eigen::Index i = 0; i < N; ++i) {
    const Eigen::Vector3f p = V.row(i);
    float best = std::numeric_limits<float>::infinity();
    for (Eigen::Index j = 0; j < J; ++j) {
      const Eigen::Vector3f b = joints.row(j);
      const Eigen::Vector3f a = parents[j] >= 0 ? Eigen::Vector3f(joints.row(parents[j])) : b;
      best = std::min(best, segment_distance(p, a, b));
    }
    out(i, 4) = J > 0 ? best / height : 0.0f;
  }

  for (const int32_t i : on_largest) out(i, 5) = 0.0f;
  const std::vector<int32_t> nearest = nearest_listed_vertices(V, on_largest, off_largest);
  for (size_t k = 0; k < off_largest.size(); ++k)
    out(off_largest[k], 5) = (V.row(off_largest[k]) - V.row(nearest[k])).norm() / height;
  return out;
}

}  // namespace amt
