#include "data_tools/garment/cloth_retarget.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "data_tools/geometry/error.h"

namespace amt {
namespace {

std::vector<int32_t> apparel_vertices(const ClothCharacter& c) {
  AMT_CHECK(int64_t(c.apparel_mask.size()) == c.mesh.V.rows(), c.name, ": apparel mask: expected ", c.mesh.V.rows(),
            " entries (one per vertex), found ", c.apparel_mask.size());
  std::vector<int32_t> apparel;
  for (size_t i = 0; i < c.apparel_mask.size(); ++i)
    if (c.apparel_mask[i]) apparel.push_back(int32_t(i));
  AMT_CHECK(!apparel.empty(), c.name, ": apparel mask: expected apparel vertices (mask 1), found none");
  return apparel;
}

// Faces whose three vertices are apparel, numbered by apparel position.
std::vector<Eigen::Vector3i> apparel_faces(const ClothCharacter& c) {
  std::vector<int32_t> position(c.apparel_mask.size(), -1);
  int32_t n = 0;
  for (size_t i = 0; i < c.apparel_mask.size(); ++i)
    if (c.apparel_mask[i]) position[i] = n++;
  std::vector<Eigen::Vector3i> faces;
  for (Eigen::Index f = 0; f < c.mesh.F.rows(); ++f) {
    Eigen::Vector3i q;
    bool all = true;
    for (int k = 0; k < 3; ++k) {
      const int32_t v = c.mesh.F(f, k);
      AMT_CHECK(v >= 0 && v < int32_t(position.size()), c.name, ": faces: expected vertex indices in [0, ",
                position.size(), "), found ", v, " in face ", f);
      q[k] = position[size_t(v)];
      all = all && q[k] >= 0;
    }
    if (all) faces.push_back(q);
  }
  return faces;
}

}  // namespace

void check_same_apparel_connectivity(const ClothCharacter& source, const ClothCharacter& target) {
  const size_t ns = apparel_vertices(source).size(), nt = apparel_vertices(target).size();
  const std::string both = target.name + " against " + source.name;
  AMT_CHECK(ns == nt, both, ": apparel connectivity differs: expected ", ns, " apparel vertices (as ", source.name,
            "), found ", nt);
  const std::vector<Eigen::Vector3i> fs = apparel_faces(source), ft = apparel_faces(target);
  AMT_CHECK(fs.size() == ft.size(), both, ": apparel connectivity differs: expected ", fs.size(),
            " apparel faces (as ", source.name, "), found ", ft.size());
  for (size_t f = 0; f < fs.size(); ++f) {
    AMT_CHECK(fs[f] == ft[f], both, ": apparel connectivity differs: apparel face ", f, " is (", ft[f][0], " ",
              ft[f][1], " ", ft[f][2], "), expected (", fs[f][0], " ", fs[f][1], " ", fs[f][2], ") as in ",
              source.name, " (apparel vertex numbering)");
  }
}

ClothRetargeter::Side ClothRetargeter::make_side(const ClothCharacter& c, const std::vector<int32_t>& apparel,
                                                 const WrapOptions& wrap) {
  Side s;
  s.num_vertices = int(c.mesh.V.rows());
  std::vector<int32_t> position(size_t(s.num_vertices), -1);
  for (int i = 0; i < s.num_vertices; ++i) {
    if (c.apparel_mask[size_t(i)]) continue;
    position[size_t(i)] = int32_t(s.body.size());
    s.body.push_back(i);
  }
  std::vector<Eigen::Vector3i> faces;
  for (Eigen::Index f = 0; f < c.mesh.F.rows(); ++f) {
    const Eigen::Vector3i q(position[size_t(c.mesh.F(f, 0))], position[size_t(c.mesh.F(f, 1))],
                            position[size_t(c.mesh.F(f, 2))]);
    if (q.minCoeff() >= 0) faces.push_back(q);
  }
  AMT_CHECK(!faces.empty(), c.name, ": body: expected faces whose three vertices are body vertices (mask 0), found none");
  s.body_faces.resize(Eigen::Index(faces.size()), 3);
  for (size_t f = 0; f < faces.size(); ++f) s.body_faces.row(Eigen::Index(f)) = faces[f].transpose();
  MatrixX3f body(Eigen::Index(s.body.size()), 3), points(Eigen::Index(apparel.size()), 3);
  for (size_t k = 0; k < s.body.size(); ++k) body.row(Eigen::Index(k)) = c.mesh.V.row(s.body[k]);
  for (size_t k = 0; k < apparel.size(); ++k) points.row(Eigen::Index(k)) = c.mesh.V.row(apparel[k]);
  const std::string source = c.name + ": wrap registration";
  s.binding = wrap_register(body, s.body_faces, points, wrap, source.c_str());
  s.clearance.resize(points.rows());
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    float c_i = 0;
    for (int k = 0; k < s.binding.k; ++k) c_i += s.binding.weight(i, k) * s.binding.local(i * s.binding.k + k, 2);
    s.clearance[i] = c_i;
  }
  std::vector<int32_t> apparel_position(c.apparel_mask.size(), -1);
  for (size_t k = 0; k < apparel.size(); ++k) apparel_position[size_t(apparel[k])] = int32_t(k);
  const MatrixX2i E = unique_edges(c.mesh.F);
  std::vector<Eigen::Vector2i> inner;
  for (Eigen::Index e = 0; e < E.rows(); ++e) {
    const int32_t a = apparel_position[size_t(E(e, 0))], b = apparel_position[size_t(E(e, 1))];
    if (a >= 0 && b >= 0) inner.emplace_back(a, b);
  }
  s.edges.resize(Eigen::Index(inner.size()), 2);
  s.rest_length.resize(Eigen::Index(inner.size()));
  for (size_t e = 0; e < inner.size(); ++e) {
    s.edges.row(Eigen::Index(e)) = inner[e].transpose();
    s.rest_length[Eigen::Index(e)] = (points.row(inner[e][0]) - points.row(inner[e][1])).norm();
  }
  return s;
}

ClothRetargeter::ClothRetargeter(const ClothCharacter& source, const ClothCharacter& target,
                                 const ClothRetargetOptions& options)
    : options_(options),
      source_name_(source.name),
      target_name_(target.name) {
  const auto start = std::chrono::steady_clock::now();
  check_same_apparel_connectivity(source, target);
  source_apparel_ = apparel_vertices(source);
  target_apparel_ = apparel_vertices(target);
  source_ = make_side(source, source_apparel_, options.wrap);
  target_ = make_side(target, target_apparel_, options.wrap);
  resolver_.emplace(target.mesh.F, target.apparel_mask, options.penetration);
  // Per apparel vertex, the size of the target apparel around it relative to the source's: the total rest
  // length of its apparel edges on the target over that on the source.
  detail_scale_ = Eigen::VectorXf::Ones(Eigen::Index(source_apparel_.size()));
  if (options.scale_details) {
    Eigen::VectorXf source_length = Eigen::VectorXf::Zero(detail_scale_.size()), target_length = source_length;
    for (const Eigen::Vector3i& f : apparel_faces(source)) {
      for (int k = 0; k < 3; ++k) {
        const int a = f[k], b = f[(k + 1) % 3];
        const float ls = (source.mesh.V.row(source_apparel_[size_t(a)]) - source.mesh.V.row(source_apparel_[size_t(b)])).norm();
        const float lt = (target.mesh.V.row(target_apparel_[size_t(a)]) - target.mesh.V.row(target_apparel_[size_t(b)])).norm();
        source_length[a] += ls, source_length[b] += ls, target_length[a] += lt, target_length[b] += lt;
      }
    }
    for (Eigen::Index i = 0; i < detail_scale_.size(); ++i)
      if (source_length[i] > 0 && target_length[i] > 0) detail_scale_[i] = target_length[i] / source_length[i];
  }
  registration_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

MatrixX3f ClothRetargeter::wrap(const Side& side, const MatrixX3f& frame, MatrixX3f* normals) const {
  MatrixX3f body(Eigen::Index(side.body.size()), 3);
  for (size_t k = 0; k < side.body.size(); ++k) body.row(Eigen::Index(k)) = frame.row(side.body[k]);
  if (normals) {
    // Weighted unit normals of each vertex's bound faces on the moved body: the inward direction of 3.1.
    const WrapBinding& b = side.binding;
    normals->setZero(b.num_points(), 3);
    for (Eigen::Index i = 0; i < b.num_points(); ++i) {
      Eigen::Vector3f n = Eigen::Vector3f::Zero();
      for (int s = 0; s < b.k; ++s) {
        const int32_t f = b.face(i, s);
        const Eigen::Vector3f p0 = body.row(side.body_faces(f, 0)), p1 = body.row(side.body_faces(f, 1)),
                              p2 = body.row(side.body_faces(f, 2));
        n += b.weight(i, s) * (p1 - p0).cross(p2 - p0).normalized();
      }
      const float length = n.norm();
      if (length > 1e-6f) normals->row(i) = (n / length).transpose();
    }
  }
  return wrap_deform(side.binding, body, side.body_faces);
}

MatrixX3f ClothRetargeter::body_oriented_source(const MatrixX3f& source_frame) const {
  AMT_CHECK(source_frame.rows() == source_.num_vertices, source_name_, ": source frame: expected ",
            source_.num_vertices, " vertices, found ", source_frame.rows());
  return wrap(source_, source_frame, nullptr);
}

MatrixX3f ClothRetargeter::body_oriented_target(const MatrixX3f& target_frame) const {
  AMT_CHECK(target_frame.rows() == target_.num_vertices, target_name_, ": target frame: expected ",
            target_.num_vertices, " vertices, found ", target_frame.rows());
  return wrap(target_, target_frame, nullptr);
}

MatrixX3f ClothRetargeter::detail_vectors(const MatrixX3f& source_frame) const {
  MatrixX3f d = body_oriented_source(source_frame);
  for (size_t k = 0; k < source_apparel_.size(); ++k)
    d.row(Eigen::Index(k)) = source_frame.row(source_apparel_[k]) - d.row(Eigen::Index(k));
  return d;
}

ClothRetargetReport ClothRetargeter::retarget(const MatrixX3f& source_frame, MatrixX3f& target_frame) {
  ClothRetargetReport report;
  const MatrixX3f d = detail_vectors(source_frame);  // steps 3 and 5
  AMT_CHECK(target_frame.rows() == target_.num_vertices, target_name_, ": target frame: expected ",
            target_.num_vertices, " vertices, found ", target_frame.rows());
  MatrixX3f normals;
  const MatrixX3f oriented = wrap(target_, target_frame, options_.detail_clearance > 0 ? &normals : nullptr);  // 4
  MatrixX3f A(d.rows(), 3);
  for (Eigen::Index k = 0; k < d.rows(); ++k) {
    Eigen::RowVector3f detail = detail_scale_[k] * d.row(k);
    if (options_.detail_clearance > 0) {
      // Section 3.1, first order: no deeper towards the body than the body-oriented vertex's clearance.
      const float inward = -detail.dot(normals.row(k));
      const float limit = options_.detail_clearance * std::max(target_.clearance[k], 0.0f);
      if (inward > limit) {
        detail *= limit / inward;
        ++report.shortened;
      }
    }
    A.row(k) = oriented.row(k) + detail;  // step 6
  }
  // Edge relaxation towards the target's rest lengths (Jacobi: every edge from the same positions).
  const MatrixX2i& E = target_.edges;
  for (int it = 0; it < options_.relax_iterations; ++it) {
    MatrixX3f move = MatrixX3f::Zero(A.rows(), 3);
    Eigen::VectorXf count = Eigen::VectorXf::Zero(A.rows());
    for (Eigen::Index e = 0; e < E.rows(); ++e) {
      const Eigen::RowVector3f v = A.row(E(e, 1)) - A.row(E(e, 0));
      const float length = v.norm();
      if (!(length > 1e-9f)) continue;
      const Eigen::RowVector3f c = (0.5f * (length - target_.rest_length[e]) / length) * v;
      move.row(E(e, 0)) += c, move.row(E(e, 1)) -= c;
      count[E(e, 0)] += 1, count[E(e, 1)] += 1;
    }
    for (Eigen::Index k = 0; k < A.rows(); ++k)
      if (count[k] > 0) A.row(k) += move.row(k) / count[k];
  }
  for (Eigen::Index k = 0; k < A.rows(); ++k) target_frame.row(target_apparel_[size_t(k)]) = A.row(k);
  if (options_.resolve) {
    const PenetrationReport r = resolver_->resolve(target_frame);  // section 3.2
    report.before = r.before;
    report.after = r.after;
  } else if (options_.measure) {
    report.before = report.after = resolver_->measure(target_frame);
  }
  return report;
}

}  // namespace amt
