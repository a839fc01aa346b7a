#include "data_tools/garment/cloth_retarget.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <utility>
#if defined(__SSE__)
#include <xmmintrin.h>
#endif

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
  // the target, listed at both ends.
  {
    std::vector<int32_t> apparel_position(target.apparel_mask.size(), -1);
    for (size_t k = 0; k < target_apparel_.size(); ++k) apparel_position[size_t(target_apparel_[k])] = int32_t(k);
    const MatrixX2i E = unique_edges(target.mesh.F);
    const int N = int(target_apparel_.size()), chunks = (N + kRelaxLanes - 1) / kRelaxLanes;
    std::vector<std::vector<std::pair<int32_t, float>>> edges(size_t(chunks * kRelaxLanes));
    for (Eigen::Index e = 0; e < E.rows(); ++e) {
      const int32_t a = apparel_position[size_t(E(e, 0))], b = apparel_position[size_t(E(e, 1))];
      if (a < 0 || b < 0) continue;
      const float rest = (target.mesh.V.row(E(e, 0)) - target.mesh.V.row(E(e, 1))).norm();
      edges[size_t(a)].emplace_back(b, rest);
      edges[size_t(b)].emplace_back(a, rest);
    }
    Relaxation& r = relaxation_;
    r.slot_begin.push_back(0);
    for (int c = 0; c < chunks; ++c) {
      size_t width = 0;
      for (int l = 0; l < kRelaxLanes; ++l) width = std::max(width, edges[size_t(c * kRelaxLanes + l)].size());
      for (size_t slot = 0; slot < width; ++slot) {
        for (int l = 0; l < kRelaxLanes; ++l) {
          const int32_t v = c * kRelaxLanes + l;
          const auto& mine = edges[size_t(v)];
          r.neighbour.push_back(slot < mine.size() ? mine[slot].first : v);
          r.rest_length.push_back(slot < mine.size() ? mine[slot].second : 0.0f);
        }
      }
      r.slot_begin.push_back(int32_t(r.neighbour.size()));
    }
    r.positions.assign(size_t(8 * chunks * kRelaxLanes), 0.0f);
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

namespace {

// One Jacobi sweep of the edge relaxation over a chunk of 4 vertices, one per lane
// (ClothRetargeter::Relaxation): each edge's correction from the current positions, half of it to this
// end, the vertex moved by the mean of its edges' corrections; edges too short for a direction move
// nothing and do not count. Positions are 4 floats per vertex (x, y, z, 0), read from `now` and written
// to `next`. A correction is (1/2) (1 - rest / length) times the edge, the same as (1/2) (length - rest)
// / length; with SSE the 1 / length is the hardware's estimate refined by a Newton step (about 1e-7
// relative), so a sweep needs neither a square root nor a division per edge.
#if defined(__SSE__)
void relax_chunk(const float* now, const int32_t* neighbour, const float* rest_length, int slots, int first,
                 float* next) {
  const float* own = now + 4 * first;
  __m128 ox = _mm_loadu_ps(own), oy = _mm_loadu_ps(own + 4), oz = _mm_loadu_ps(own + 8), ow = _mm_loadu_ps(own + 12);
  _MM_TRANSPOSE4_PS(ox, oy, oz, ow);  // x, y, z of the 4 lanes
  const __m128 half = _mm_set1_ps(0.5f), one = _mm_set1_ps(1.0f), three_halves = _mm_set1_ps(1.5f);
  const __m128 shortest2 = _mm_set1_ps(1e-18f);  // edges of 1e-9 m or less have no direction
  __m128 move_x = _mm_setzero_ps(), move_y = _mm_setzero_ps(), move_z = _mm_setzero_ps(), count = _mm_setzero_ps();
  for (int s = 0; s < slots; ++s) {
    const int32_t* j = neighbour + 4 * s;
    __m128 x = _mm_loadu_ps(now + 4 * j[0]), y = _mm_loadu_ps(now + 4 * j[1]), z = _mm_loadu_ps(now + 4 * j[2]),
           w = _mm_loadu_ps(now + 4 * j[3]);
    _MM_TRANSPOSE4_PS(x, y, z, w);
    const __m128 dx = _mm_sub_ps(x, ox), dy = _mm_sub_ps(y, oy), dz = _mm_sub_ps(z, oz);
    const __m128 length2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
    const __m128 counted = _mm_cmpgt_ps(length2, shortest2);
    __m128 inverse = _mm_rsqrt_ps(length2);  // inf for a zero length: masked out below
    inverse = _mm_mul_ps(inverse, _mm_sub_ps(three_halves, _mm_mul_ps(_mm_mul_ps(half, length2),
                                                                      _mm_mul_ps(inverse, inverse))));
    const __m128 c = _mm_and_ps(counted, _mm_mul_ps(half, _mm_sub_ps(one, _mm_mul_ps(_mm_loadu_ps(rest_length + 4 * s),
                                                                                       inverse))));
    move_x = _mm_add_ps(move_x, _mm_mul_ps(c, dx));
    move_y = _mm_add_ps(move_y, _mm_mul_ps(c, dy));
    move_z = _mm_add_ps(move_z, _mm_mul_ps(c, dz));
    count = _mm_add_ps(count, _mm_and_ps(counted, one));
  }
  const __m128 n = _mm_max_ps(count, one);
  __m128 x = _mm_add_ps(ox, _mm_div_ps(move_x, n)), y = _mm_add_ps(oy, _mm_div_ps(move_y, n)),
         z = _mm_add_ps(oz, _mm_div_ps(move_z, n)), w = _mm_setzero_ps();
  _MM_TRANSPOSE4_PS(x, y, z, w);
  float* out = next + 4 * first;
  _mm_storeu_ps(out, x), _mm_storeu_ps(out + 4, y), _mm_storeu_ps(out + 8, z), _mm_storeu_ps(out + 12, w);
}
#else
void relax_chunk(const float* now, const int32_t* neighbour, const float* rest_length, int slots, int first,
                 float* next) {
  for (int l = 0; l < 4; ++l) {
    const float* own = now + 4 * (first + l);
    float move[3] = {}, count = 0;
    for (int s = 0; s < slots; ++s) {
      const float* other = now + 4 * neighbour[4 * s + l];
      const float d[3] = {other[0] - own[0], other[1] - own[1], other[2] - own[2]};
      const float length = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      if (!(length > 1e-9f)) continue;
      const float c = 0.5f * (length - rest_length[4 * s + l]) / length;
      for (int k = 0; k < 3; ++k) move[k] += c * d[k];
      count += 1;
    }
    float* out = next + 4 * (first + l);
    for (int k = 0; k < 3; ++k) out[k] = own[k] + (count > 0 ? move[k] / count : 0.0f);
    out[3] = 0;
  }
}
#endif

}  // namespace

// Edge relaxation towards the target's rest lengths, Jacobi: every edge's correction from the same
// positions, half to each end, each vertex moved by the mean of its edges' corrections. Each vertex
// gathers its own edges (every edge is evaluated at both ends), so that vertices run side by side in
// vector lanes and nothing is scattered; no allocation.
void ClothRetargeter::relax(MatrixX3f& A) {
  static_assert(kRelaxLanes == 4, "relax_chunk runs 4 lanes");
  if (options_.relax_iterations <= 0) return;
  Relaxation& r = relaxation_;
  const int N = int(A.rows()), chunks = int(r.slot_begin.size()) - 1, padded = chunks * kRelaxLanes;
  float* now = r.positions.data();
  float* next = now + 4 * padded;
  for (int k = 0; k < N; ++k) now[4 * k] = A(k, 0), now[4 * k + 1] = A(k, 1), now[4 * k + 2] = A(k, 2);
  for (int it = 0; it < options_.relax_iterations; ++it) {
    for (int c = 0; c < chunks; ++c) {
      const int32_t begin = r.slot_begin[size_t(c)];
      relax_chunk(now, r.neighbour.data() + begin, r.rest_length.data() + begin,
                  (r.slot_begin[size_t(c) + 1] - begin) / kRelaxLanes, c * kRelaxLanes, next);
    }
    std::swap(now, next);
  }
  for (int k = 0; k < N; ++k) A.row(k) << now[4 * k], now[4 * k + 1], now[4 * k + 2];
}

}  // namespace amt
