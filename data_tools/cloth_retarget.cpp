#include "data_tools/cloth_retarget.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <utility>

#include "data_tools/error.h"

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
  std::vector<int32_t> body, position(size_t(s.num_vertices), -1);  // body: vertex ids of the body part, ascending
  for (int i = 0; i < s.num_vertices; ++i) {
    if (c.apparel_mask[size_t(i)]) continue;
    position[size_t(i)] = int32_t(body.size());
    body.push_back(i);
  }
  std::vector<Eigen::Vector3i> faces;  // faces with three body vertices, as vertex ids
  for (Eigen::Index f = 0; f < c.mesh.F.rows(); ++f) {
    const Eigen::Vector3i q = c.mesh.F.row(f).transpose();
    if (position[size_t(q[0])] >= 0 && position[size_t(q[1])] >= 0 && position[size_t(q[2])] >= 0) faces.push_back(q);
  }
  AMT_CHECK(!faces.empty(), c.name, ": body: expected faces whose three vertices are body vertices (mask 0), found none");
  // Registered against the body part alone (faces numbered into `body`), deformed from whole frames.
  MatrixX3i body_faces(Eigen::Index(faces.size()), 3), frame_faces(Eigen::Index(faces.size()), 3);
  for (size_t f = 0; f < faces.size(); ++f) {
    frame_faces.row(Eigen::Index(f)) = faces[f].transpose();
    for (int k = 0; k < 3; ++k) body_faces(Eigen::Index(f), k) = position[size_t(faces[f][k])];
  }
  MatrixX3f body_rest(Eigen::Index(body.size()), 3), points(Eigen::Index(apparel.size()), 3);
  for (size_t k = 0; k < body.size(); ++k) body_rest.row(Eigen::Index(k)) = c.mesh.V.row(body[k]);
  for (size_t k = 0; k < apparel.size(); ++k) points.row(Eigen::Index(k)) = c.mesh.V.row(apparel[k]);
  const std::string source = c.name + ": wrap registration";
  WrapBinding binding = wrap_register(body_rest, body_faces, points, wrap, source.c_str());
  s.clearance.resize(points.rows());
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    float c_i = 0;
    for (int k = 0; k < binding.k; ++k) c_i += binding.weight(i, k) * binding.local(i * binding.k + k, 2);
    s.clearance[i] = c_i;
  }
  s.wrap = WrapDeformer(std::move(binding), frame_faces);
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
  // The relaxation's edges: mesh edges with two apparel ends, by apparel position, and their rest lengths on
  // the target.
  {
    std::vector<int32_t> apparel_position(target.apparel_mask.size(), -1);
    for (size_t k = 0; k < target_apparel_.size(); ++k) apparel_position[size_t(target_apparel_[k])] = int32_t(k);
    const MatrixX2i E = unique_edges(target.mesh.F);
    std::vector<int> degree(target_apparel_.size(), 0);
    for (Eigen::Index e = 0; e < E.rows(); ++e) {
      const int32_t a = apparel_position[size_t(E(e, 0))], b = apparel_position[size_t(E(e, 1))];
      if (a < 0 || b < 0) continue;
      relaxation_.ends.push_back(a);
      relaxation_.ends.push_back(b);
      relaxation_.rest_length.push_back((target.mesh.V.row(E(e, 0)) - target.mesh.V.row(E(e, 1))).norm());
      ++degree[size_t(a)], ++degree[size_t(b)];
    }
    relaxation_.inverse_degree.resize(degree.size());
    for (size_t k = 0; k < degree.size(); ++k)
      relaxation_.inverse_degree[k] = degree[k] > 0 ? 1.0f / float(degree[k]) : 0.0f;
  }
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

MatrixX3f ClothRetargeter::body_oriented_source(const MatrixX3f& source_frame) const {
  AMT_CHECK(source_frame.rows() == source_.num_vertices, source_name_, ": source frame: expected ",
            source_.num_vertices, " vertices, found ", source_frame.rows());
  MatrixX3f out;
  WrapDeformer::Frames frames;
  source_.wrap.deform(source_frame, out, nullptr, frames);
  return out;
}

MatrixX3f ClothRetargeter::body_oriented_target(const MatrixX3f& target_frame) const {
  AMT_CHECK(target_frame.rows() == target_.num_vertices, target_name_, ": target frame: expected ",
            target_.num_vertices, " vertices, found ", target_frame.rows());
  MatrixX3f out;
  WrapDeformer::Frames frames;
  target_.wrap.deform(target_frame, out, nullptr, frames);
  return out;
}

MatrixX3f ClothRetargeter::detail_vectors(const MatrixX3f& source_frame) const {
  MatrixX3f d = body_oriented_source(source_frame);
  for (size_t k = 0; k < source_apparel_.size(); ++k)
    d.row(Eigen::Index(k)) = source_frame.row(source_apparel_[k]) - d.row(Eigen::Index(k));
  return d;
}

ClothRetargetReport ClothRetargeter::retarget(const MatrixX3f& source_frame, MatrixX3f& target_frame) {
  ClothRetargetReport report;
  AMT_CHECK(source_frame.rows() == source_.num_vertices, source_name_, ": source frame: expected ",
            source_.num_vertices, " vertices, found ", source_frame.rows());
  AMT_CHECK(target_frame.rows() == target_.num_vertices, target_name_, ": target frame: expected ",
            target_.num_vertices, " vertices, found ", target_frame.rows());
  source_.wrap.deform(source_frame, oriented_source_, nullptr, frames_);  // step 3: body-oriented source apparel
  const bool shorten = options_.detail_clearance > 0;
  target_.wrap.deform(target_frame, oriented_target_, shorten ? &normals_ : nullptr, frames_);  // 4
  const Eigen::Index N = oriented_target_.rows();
  apparel_.resize(N, 3);
  for (Eigen::Index k = 0; k < N; ++k) {
    // Step 5, the detail vector, scaled.
    Eigen::RowVector3f detail =
        detail_scale_[k] * (source_frame.row(source_apparel_[size_t(k)]) - oriented_source_.row(k));
    if (shorten) {
      // Section 3.1, first order: no deeper towards the body than the body-oriented vertex's clearance.
      const float inward = -detail.dot(normals_.row(k));
      const float limit = options_.detail_clearance * std::max(target_.clearance[k], 0.0f);
      if (inward > limit) {
        detail *= limit / inward;
        ++report.shortened;
      }
    }
    apparel_.row(k) = oriented_target_.row(k) + detail;  // step 6
  }
  relax(apparel_);
  for (Eigen::Index k = 0; k < N; ++k) target_frame.row(target_apparel_[size_t(k)]) = apparel_.row(k);
  if (options_.resolve) {
    const PenetrationReport r = resolver_->resolve(target_frame);  // section 3.2
    report.before = r.before;
    report.after = r.after;
  } else if (options_.measure) {
    report.before = report.after = resolver_->measure(target_frame);
  }
  return report;
}

// Edge relaxation towards the target's rest lengths, Jacobi: every edge's correction from the same
// positions, half to each end, each vertex moved by the mean of its edges' corrections. Flat arrays and no
// allocation: this runs relax_iterations times over every apparel edge, per frame.
void ClothRetargeter::relax(MatrixX3f& A) {
  Relaxation& r = relaxation_;
  float* P = A.data();  // row-major: x, y, z of vertex k at 3k
  const int32_t* ends = r.ends.data();
  const float* rest = r.rest_length.data();
  const size_t num_edges = r.rest_length.size(), n3 = size_t(3 * A.rows());
  r.move.resize(n3);
  float* move = r.move.data();
  for (int it = 0; it < options_.relax_iterations; ++it) {
    std::fill(r.move.begin(), r.move.end(), 0.0f);
    bool degenerate = false;  // an edge too short for a direction: it moves nothing and does not count
    for (size_t e = 0; e < num_edges; ++e) {
      float* a = move + 3 * ends[2 * e];
      float* b = move + 3 * ends[2 * e + 1];
      const float* pa = P + 3 * ends[2 * e];
      const float* pb = P + 3 * ends[2 * e + 1];
      const float x = pb[0] - pa[0], y = pb[1] - pa[1], z = pb[2] - pa[2];
      const float length = std::sqrt(x * x + y * y + z * z);
      if (!(length > 1e-9f)) {
        degenerate = true;
        continue;
      }
      const float c = 0.5f * (length - rest[e]) / length;
      a[0] += c * x, a[1] += c * y, a[2] += c * z;
      b[0] -= c * x, b[1] -= c * y, b[2] -= c * z;
    }
    if (!degenerate) {
      for (size_t k = 0; k < n3 / 3; ++k) {
        const float w = r.inverse_degree[k];
        P[3 * k] += move[3 * k] * w, P[3 * k + 1] += move[3 * k + 1] * w, P[3 * k + 2] += move[3 * k + 2] * w;
      }
      continue;
    }
    // Rare: count each vertex's edges that had a direction.
    std::vector<int> count(size_t(A.rows()), 0);
    for (size_t e = 0; e < num_edges; ++e) {
      const float* pa = P + 3 * ends[2 * e];
      const float* pb = P + 3 * ends[2 * e + 1];
      const float x = pb[0] - pa[0], y = pb[1] - pa[1], z = pb[2] - pa[2];
      if (std::sqrt(x * x + y * y + z * z) > 1e-9f) ++count[size_t(ends[2 * e])], ++count[size_t(ends[2 * e + 1])];
    }
    for (size_t i = 0; i < n3; ++i)
      if (count[i / 3] > 0) P[i] += move[i] / float(count[i / 3]);
  }
}

}  // namespace amt
