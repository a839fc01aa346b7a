#include "data_tools/geometry/segmentation_features.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <unordered_map>

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

// Checks V, F, joints and parents as the file comment says.
void check_inputs(const MatrixX3f& V, const MatrixX3i& F, const MatrixX3f& joints, const std::vector<int32_t>& parents) {
  validate_mesh(TriMesh{V, F}, "segmentation features");
  const Eigen::Index J = joints.rows();
  AMT_CHECK(static_cast<Eigen::Index>(parents.size()) == J, "segmentation features: parents: expected ", J,
            " (one per joint), found ", parents.size());
  for (Eigen::Index j = 0; j < J; ++j) {
    AMT_CHECK(joints.row(j).allFinite(), "segmentation features: joints: expected finite positions, found joint ", j,
              " at ", joints(j, 0), " ", joints(j, 1), " ", joints(j, 2));
    AMT_CHECK(parents[j] >= -1 && parents[j] < J, "segmentation features: parents: expected -1 or a joint in [0, ", J,
              "), found ", parents[j], " for joint ", j);
  }
}

// Distance from each vertex to the nearest bone segment (joint to parent), over `height`.
void bone_distance_column(const MatrixX3f& V, const MatrixX3f& joints, const std::vector<int32_t>& parents,
                          float height, MatrixXfR& out, int column) {
  const Eigen::Index J = joints.rows();
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    const Eigen::Vector3f p = V.row(i);
    float best = std::numeric_limits<float>::infinity();
    for (Eigen::Index j = 0; j < J; ++j) {
      const Eigen::Vector3f b = joints.row(j);
      const Eigen::Vector3f a = parents[j] >= 0 ? Eigen::Vector3f(joints.row(parents[j])) : b;
      best = std::min(best, segment_distance(p, a, b));
    }
    out(i, column) = J > 0 ? best / height : 0.0f;
  }
}

// Columns 3 and 5 from each vertex's part label (any integers in [0, N)): the share of the counted
// vertices in the vertex's part, and the distance to the nearest vertex of the part with the most
// counted vertices (0 on it) over `height`.
void part_columns(const MatrixX3f& V, const std::vector<int32_t>& part, const std::vector<uint8_t>& counted,
                  float height, MatrixXfR& out) {
  const Eigen::Index N = V.rows();
  std::vector<int32_t> size(static_cast<size_t>(N), 0);
  int32_t total = 0;
  for (Eigen::Index i = 0; i < N; ++i)
    if (counted[size_t(i)]) ++size[size_t(part[size_t(i)])], ++total;
  const int32_t largest = static_cast<int32_t>(std::max_element(size.begin(), size.end()) - size.begin());
  std::vector<int32_t> on_largest, off_largest;
  for (Eigen::Index i = 0; i < N; ++i) {
    out(i, 3) = static_cast<float>(size[size_t(part[size_t(i)])]) / static_cast<float>(std::max(total, 1));
    out(i, 5) = 0.0f;
    (part[size_t(i)] == largest ? on_largest : off_largest).push_back(static_cast<int32_t>(i));
  }
  const std::vector<int32_t> nearest = nearest_listed_vertices(V, on_largest, off_largest);
  for (size_t k = 0; k < off_largest.size(); ++k)
    out(off_largest[k], 5) = (V.row(off_largest[k]) - V.row(nearest[k])).norm() / height;
}

int32_t find_root(std::vector<int32_t>& up, int32_t i) {
  while (up[size_t(i)] != i) i = up[size_t(i)] = up[size_t(up[size_t(i)])];
  return i;
}

void unite(std::vector<int32_t>& up, int32_t a, int32_t b) {
  a = find_root(up, a), b = find_root(up, b);
  if (a != b) up[size_t(std::max(a, b))] = std::min(a, b);
}

}  // namespace

std::vector<int32_t> weld_vertices(const MatrixX3f& V, float tolerance) {
  AMT_CHECK(std::isfinite(tolerance) && tolerance >= 0, "weld vertices: tolerance: expected >= 0 metres, found ",
            tolerance);
  const int32_t N = static_cast<int32_t>(V.rows());
  std::vector<int32_t> up(static_cast<size_t>(N));
  std::iota(up.begin(), up.end(), 0);
  // A hash grid of cell `tolerance`: welded pairs lie in the same or neighbouring cells.
  const float cell = std::max(tolerance, 1e-7f);
  const auto key = [](int64_t x, int64_t y, int64_t z) {
    return (x * 73856093) ^ (y * 19349663) ^ (z * 83492791);
  };
  std::unordered_map<int64_t, std::vector<int32_t>> grid;
  std::vector<Eigen::Vector3i> cells(static_cast<size_t>(N));
  for (int32_t i = 0; i < N; ++i) {
    for (int k = 0; k < 3; ++k) cells[size_t(i)][k] = static_cast<int>(std::floor(V(i, k) / cell));
    grid[key(cells[size_t(i)].x(), cells[size_t(i)].y(), cells[size_t(i)].z())].push_back(i);
  }
  const float tol2 = tolerance * tolerance;
  for (int32_t i = 0; i < N; ++i) {
    const Eigen::Vector3i c = cells[size_t(i)];
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const auto it = grid.find(key(c.x() + dx, c.y() + dy, c.z() + dz));
          if (it == grid.end()) continue;
          for (const int32_t j : it->second)
            if (j < i && (V.row(i) - V.row(j)).squaredNorm() <= tol2) unite(up, i, j);
        }
  }
  for (int32_t i = 0; i < N; ++i) up[size_t(i)] = find_root(up, i);
  return up;
}

MatrixXfR welded_segmentation_features(const MatrixX3f& V, const MatrixX3i& F, const MatrixX3f& joints,
                                       const std::vector<int32_t>& parents, float tolerance) {
  check_inputs(V, F, joints, parents);
  const Eigen::Index N = V.rows();
  const float height = std::max(V.col(1).maxCoeff() - V.col(1).minCoeff(), 1e-6f);
  const std::vector<int32_t> weld = weld_vertices(V, tolerance);
  MatrixXfR out = MatrixXfR::Zero(N, kSegmentationFeatures);

  // Normals: area-weighted face normals summed on the welded point, then spread to its copies.
  MatrixX3f sum = MatrixX3f::Zero(N, 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const Eigen::Vector3f a = V.row(F(f, 0)), b = V.row(F(f, 1)), c = V.row(F(f, 2));
    const Eigen::Vector3f n = (b - a).cross(c - a);  // twice the area times the unit normal
    for (int k = 0; k < 3; ++k) sum.row(weld[size_t(F(f, k))]) += n.transpose();
  }
  for (Eigen::Index i = 0; i < N; ++i) {
    const Eigen::Vector3f n = sum.row(weld[size_t(i)]);
    const float len = n.norm();
    if (len > 1e-20f) out.block<1, 3>(i, 0) = (n / len).transpose();
  }

  // Parts over the faces' edges between welded points; sizes count welded points, not copies.
  std::vector<int32_t> up(static_cast<size_t>(N));
  std::iota(up.begin(), up.end(), 0);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) unite(up, weld[size_t(F(f, k))], weld[size_t(F(f, (k + 1) % 3))]);
  std::vector<int32_t> part(static_cast<size_t>(N));
  std::vector<uint8_t> counted(static_cast<size_t>(N));
  for (Eigen::Index i = 0; i < N; ++i) {
    part[size_t(i)] = find_root(up, weld[size_t(i)]);
    counted[size_t(i)] = weld[size_t(i)] == i;
  }
  part_columns(V, part, counted, height, out);
  bone_distance_column(V, joints, parents, height, out, 4);
  return out;
}

MatrixXfR segmenter_input_features(const std::string& inputs, const MatrixX3f& V, const MatrixX3i& F,
                                   const MatrixX3f& joints, const std::vector<int32_t>& parents) {
  if (inputs == "shape") return segmentation_features(V, F, joints, parents);
  if (inputs == "welded") return welded_segmentation_features(V, F, joints, parents);
  AMT_CHECK(inputs == "positions", "segmenter features: inputs: expected \"shape\", \"welded\" or \"positions\", found \"",
            inputs, "\"");
  return MatrixXfR(V.rows(), 0);
}

MatrixXfR segmentation_features(const MatrixX3f& V, const MatrixX3i& F, const MatrixX3f& joints,
                                const std::vector<int32_t>& parents) {
  check_inputs(V, F, joints, parents);
  const Eigen::Index N = V.rows();
  const float height = std::max(V.col(1).maxCoeff() - V.col(1).minCoeff(), 1e-6f);
  MatrixXfR out(N, kSegmentationFeatures);
  out.leftCols<3>() = vertex_normals(V, F);
  const std::vector<int32_t> label = connected_components(static_cast<int>(N), unique_edges(F));
  part_columns(V, label, std::vector<uint8_t>(static_cast<size_t>(N), 1), height, out);
  bone_distance_column(V, joints, parents, height, out, 4);
  return out;
}

}  // namespace amt
