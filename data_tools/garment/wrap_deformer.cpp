#include "data_tools/garment/wrap_deformer.h"

#include <algorithm>
#include <cmath>
#include <nanoflann.hpp>
#include <numeric>
#include <utility>

#include "data_tools/geometry/error.h"

namespace amt {
namespace {

// nanoflann adaptor over the centroids of the registrable faces.
struct CentroidCloud {
  const MatrixX3f& C;
  size_t kdtree_get_point_count() const { return static_cast<size_t>(C.rows()); }
  float kdtree_get_pt(size_t index, size_t dim) const {
    return C(static_cast<Eigen::Index>(index), static_cast<Eigen::Index>(dim));
  }
  template <class BoundingBox>
  bool kdtree_get_bbox(BoundingBox&) const {
    return false;
  }
};
using CentroidTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, CentroidCloud>, CentroidCloud, 3, uint32_t>;

void check_rows_finite(const MatrixX3f& P, const char* source, const char* field) {
  for (Eigen::Index i = 0; i < P.rows(); ++i) {
    AMT_CHECK(P.row(i).allFinite(), source, ": ", field, ": expected finite values, found ", P(i, 0), " ", P(i, 1), " ",
              P(i, 2), " at row ", i);
  }
}

// The frame of the triangle (a, b, c), as face_frame documents it.
bool triangle_frame(const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& c, Eigen::Matrix3f& R,
                    Eigen::Vector3f& centroid) {
  centroid = (a + b + c) / 3.0f;
  const Eigen::Vector3f normal = (b - a).cross(c - a);
  const float edge = (b - a).norm(), area2 = normal.norm();
  // Zero area relative to the edge: no normal to speak of.
  if (!(edge > 0) || !(area2 > 1e-12f * std::max(edge * edge, 1e-30f))) {
    R.setIdentity();
    return false;
  }
  const Eigen::Vector3f e1 = (b - a) / edge, n = normal / area2;
  R.row(0) = e1.transpose();
  R.row(1) = n.cross(e1).transpose();
  R.row(2) = n.transpose();
  return true;
}

}  // namespace

float point_triangle_distance2(const Eigen::Vector3f& p, const Eigen::Vector3f& a, const Eigen::Vector3f& b,
                               const Eigen::Vector3f& c) {
  // The closest point by Voronoi region (Ericson 2005, section 5.1.5).
  const Eigen::Vector3f ab = b - a, ac = c - a, ap = p - a;
  const float d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return ap.squaredNorm();
  const Eigen::Vector3f bp = p - b;
  const float d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return bp.squaredNorm();
  const float vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return (ap - (d1 / (d1 - d3)) * ab).squaredNorm();
  const Eigen::Vector3f cp = p - c;
  const float d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return cp.squaredNorm();
  const float vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return (ap - (d2 / (d2 - d6)) * ac).squaredNorm();
  const float va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const float w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return (bp - w * (c - b)).squaredNorm();
  }
  const float denominator = 1.0f / (va + vb + vc);
  const float v = vb * denominator, w = vc * denominator;
  return (ap - ab * v - ac * w).squaredNorm();
}

bool face_frame(const MatrixX3f& V, const MatrixX3i& F, int64_t f, Eigen::Matrix3f& R, Eigen::Vector3f& centroid) {
  return triangle_frame(V.row(F(f, 0)).transpose(), V.row(F(f, 1)).transpose(), V.row(F(f, 2)).transpose(), R,
                        centroid);
}

WrapBinding wrap_register(const MatrixX3f& V, const MatrixX3i& F, const MatrixX3f& points, const WrapOptions& options,
                          const char* source) {
  AMT_CHECK(options.faces >= 1, source, ": faces: expected >= 1, found ", options.faces);
  AMT_CHECK(options.candidates >= options.faces, source, ": candidates: expected >= faces (", options.faces,
            "), found ", options.candidates);
  AMT_CHECK(std::isfinite(options.min_plane_distance) && options.min_plane_distance > 0, source,
            ": min_plane_distance: expected a distance > 0, found ", options.min_plane_distance);
  check_rows_finite(V, source, "deformer vertices");
  check_rows_finite(points, source, "points");
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    for (int j = 0; j < 3; ++j) {
      AMT_CHECK(F(f, j) >= 0 && F(f, j) < V.rows(), source, ": deformer face ", f, ": expected vertex indices in [0, ",
                V.rows(), "), found ", F(f, j));
    }
  }
  // The faces that have a frame, and their centroids.
  std::vector<int32_t> usable;
  std::vector<Eigen::Matrix3f> frames;
  std::vector<Eigen::Vector3f> centres;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    Eigen::Matrix3f R;
    Eigen::Vector3f c;
    if (!face_frame(V, F, f, R, c)) continue;
    usable.push_back(static_cast<int32_t>(f));
    frames.push_back(R);
    centres.push_back(c);
  }
  AMT_CHECK(!usable.empty(), source, ": deformer: expected at least one face of non-zero area, found none (",
            F.rows(), " faces)");
  const int k = std::min<int>(options.faces, static_cast<int>(usable.size()));
  const int candidates = std::min<int>(options.candidates, static_cast<int>(usable.size()));
  MatrixX3f C(static_cast<Eigen::Index>(usable.size()), 3);
  for (size_t u = 0; u < usable.size(); ++u) C.row(static_cast<Eigen::Index>(u)) = centres[u].transpose();
  const CentroidCloud cloud{C};
  const CentroidTree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));  // built here

  WrapBinding binding;
  binding.k = k;
  const Eigen::Index N = points.rows();
  binding.face.resize(N, k);
  binding.weight.resize(N, k);
  binding.local.resize(N * k, 3);
  binding.rest_offset.resize(N * k, 3);
  std::vector<uint32_t> nearest(static_cast<size_t>(candidates));
  std::vector<float> centroid_d2(static_cast<size_t>(candidates));
  std::vector<std::pair<float, uint32_t>> ranked;
  for (Eigen::Index i = 0; i < N; ++i) {
    const Eigen::Vector3f p = points.row(i).transpose();
    const size_t found = tree.knnSearch(p.data(), static_cast<size_t>(candidates), nearest.data(), centroid_d2.data());
    ranked.clear();
    for (size_t q = 0; q < found; ++q) {
      const int32_t f = usable[nearest[q]];
      const float d2 = point_triangle_distance2(p, V.row(F(f, 0)).transpose(), V.row(F(f, 1)).transpose(),
                                                V.row(F(f, 2)).transpose());
      ranked.emplace_back(d2, nearest[q]);
    }
    // Nearest first; ties by face index, so the binding does not depend on the tree's order.
    std::sort(ranked.begin(), ranked.end(), [&](const auto& x, const auto& y) {
      return x.first != y.first ? x.first < y.first : usable[x.second] < usable[y.second];
    });
    float total = 0;
    for (int s = 0; s < k; ++s) {
      const uint32_t u = ranked[static_cast<size_t>(s)].second;
      const Eigen::Vector3f local = frames[u] * (p - centres[u]);
      binding.face(i, s) = usable[u];
      binding.local.row(i * k + s) = local.transpose();
      binding.rest_offset.row(i * k + s) = (p - centres[u]).transpose();
      // local.z() is the signed distance to the face's plane; ranked[s].first the squared distance to the face.
      const float distance = options.triangle_distance_weights ? std::sqrt(ranked[size_t(s)].first) : std::abs(local.z());
      const float w = 1.0f / std::max(distance, options.min_plane_distance);
      binding.weight(i, s) = w;
      total += w;
    }
    binding.weight.row(i) /= total;
  }
  return binding;
}

MatrixX3f wrap_deform(const WrapBinding& binding, const MatrixX3f& V_moved, const MatrixX3i& F) {
  MatrixX3f out;
  WrapDeformer::Frames frames;
  WrapDeformer(binding, F).deform(V_moved, out, nullptr, frames);
  return out;
}

WrapDeformer::WrapDeformer(WrapBinding binding, const MatrixX3i& corners) : binding_(std::move(binding)) {
  const int64_t N = binding_.num_points();
  const int k = binding_.k;
  // The used faces in order of first use, each once.
  std::vector<int32_t> used(static_cast<size_t>(corners.rows()), -1);
  slot_.resize(static_cast<size_t>(N * k));
  for (int64_t i = 0; i < N; ++i) {
    for (int s = 0; s < k; ++s) {
      const int32_t f = binding_.face(i, s);
      AMT_CHECK(f >= 0 && f < corners.rows(), "wrap deformer: binding: expected faces in [0, ", corners.rows(),
                "), found ", f);
      if (used[static_cast<size_t>(f)] < 0) {
        used[static_cast<size_t>(f)] = static_cast<int32_t>(corners_.size() / 3);
        for (int j = 0; j < 3; ++j) corners_.push_back(corners(f, j));
      }
      slot_[static_cast<size_t>(i * k + s)] = used[static_cast<size_t>(f)];
      const float w = binding_.weight(i, s);
      weighted_.push_back(w);
      for (int j = 0; j < 3; ++j) weighted_.push_back(w * binding_.local(i * k + s, j));
      for (int j = 0; j < 3; ++j) weighted_.push_back(w * binding_.rest_offset(i * k + s, j));
    }
  }
}

void WrapDeformer::deform(const MatrixX3f& V, MatrixX3f& out, MatrixX3f* normals, Frames& frames) const {
  constexpr int kStride = 15;  // centroid, e1, e2, n, unit normal
  const int faces = num_used_faces();
  frames.data.resize(static_cast<size_t>(kStride * faces));
  frames.collapsed.resize(static_cast<size_t>(faces));
  for (int u = 0; u < faces; ++u) {
    const int32_t* c = &corners_[static_cast<size_t>(3 * u)];
    const Eigen::Vector3f a = V.row(c[0]).transpose(), b = V.row(c[1]).transpose(), d = V.row(c[2]).transpose();
    Eigen::Matrix3f R;
    Eigen::Vector3f centroid;
    const bool collapsed = !triangle_frame(a, b, d, R, centroid);
    frames.collapsed[static_cast<size_t>(u)] = collapsed;
    float* f = &frames.data[static_cast<size_t>(kStride * u)];
    const auto put = [f](int at, const Eigen::Vector3f& v) { f[at] = v[0], f[at + 1] = v[1], f[at + 2] = v[2]; };
    put(0, centroid);
    for (int r = 0; r < 3; ++r) put(3 + 3 * r, R.row(r).transpose());
    // The unit normal: n of the frame, or of a face too thin for a frame (zero for no area at all).
    put(12, collapsed ? Eigen::Vector3f((b - a).cross(d - a).normalized()) : Eigen::Vector3f(R.row(2).transpose()));
  }
  const int64_t N = binding_.num_points();
  const int k = binding_.k;
  out.resize(N, 3);
  if (normals) normals->resize(N, 3);
  for (int64_t i = 0; i < N; ++i) {
    Eigen::Vector3f p = Eigen::Vector3f::Zero(), n = Eigen::Vector3f::Zero();
    for (int s = 0; s < k; ++s) {
      const auto u = static_cast<size_t>(slot_[static_cast<size_t>(i * k + s)]);
      const float* f = &frames.data[kStride * u];
      const float* w = &weighted_[static_cast<size_t>(7 * (i * k + s))];  // w, w * local, w * rest_offset
      // w (centroid + offset), the offset the local coordinates in the face's frame (or the rest offset).
      p += w[0] * Eigen::Map<const Eigen::Vector3f>(f);
      if (frames.collapsed[u]) {
        p += Eigen::Map<const Eigen::Vector3f>(w + 4);
      } else {
        p += Eigen::Map<const Eigen::Vector3f>(f + 3) * w[1] + Eigen::Map<const Eigen::Vector3f>(f + 6) * w[2] +
             Eigen::Map<const Eigen::Vector3f>(f + 9) * w[3];
      }
      if (normals) n += w[0] * Eigen::Map<const Eigen::Vector3f>(f + 12);
    }
    out.row(i) = p.transpose();
    if (normals) {
      const float length = n.norm();
      normals->row(i) = length > 1e-6f ? Eigen::RowVector3f(n.transpose() / length) : Eigen::RowVector3f::Zero();
    }
  }
}

}  // namespace amt
