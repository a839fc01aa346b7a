#include "data_tools/builder/artist_style.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <map>
#include <numeric>
#include <random>
#include <unordered_map>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/segmentation_features.h"
#include "data_tools/geometry/skeleton.h"

namespace amt {
namespace {

constexpr float kPi = 3.14159265358979f;

// Uniform draws from the generator's bits (std:: distributions differ between standard libraries).
struct Draws {
  std::mt19937_64 bits;
  double uniform() { return static_cast<double>(bits() >> 11) * 0x1.0p-53; }
  float uniform(float low, float high) { return low + static_cast<float>(uniform()) * (high - low); }
};

int64_t edge_key(int32_t a, int32_t b, int64_t n) {
  return a < b ? a * n + b : b * n + a;
}

// The source subdivided at the midpoints of its longest edges (ArtistStyleCharacter's "subdivided source").
//   V, F       the subdivided mesh: the N source vertices, then the midpoints
//   pairs      per vertex its source edge (a == b for a source vertex)
//   mask, W    apparel mask (a midpoint is apparel when either end is) and body weights (the ends' mean)
//   body       per vertex: on the body (the source's leading body run, or a midpoint of two body vertices)
struct Subdivided {
  MatrixX3f V;
  MatrixX3i F;
  std::vector<Eigen::Vector2i> pairs;
  std::vector<uint8_t> mask, body;
  MatrixXfR W;
};

// Splits the `splits` longest edges (ties at the threshold all split, so that coincident edges of the source,
// equal in length, split alike) and re-triangulates each face 1-to-2, 3 or 4.
Subdivided subdivide(const CharacterData& c, int body_vertices, int64_t splits) {
  const int N = c.mesh.num_vertices();
  const MatrixX2i E = unique_edges(c.mesh.F);
  const Eigen::VectorXf L = edge_lengths(c.mesh.V, E);
  float threshold = std::numeric_limits<float>::infinity();
  if (splits >= E.rows()) {
    threshold = -1.0f;
  } else if (splits > 0) {
    std::vector<float> sorted(L.data(), L.data() + L.size());
    std::nth_element(sorted.begin(), sorted.begin() + (splits - 1), sorted.end(), std::greater<float>());
    threshold = sorted[size_t(splits - 1)];
  }
  Subdivided s;
  std::unordered_map<int64_t, int32_t> midpoint;
  for (int v = 0; v < N; ++v) s.pairs.emplace_back(v, v);
  for (Eigen::Index e = 0; e < E.rows(); ++e) {
    if (!(L[e] >= threshold)) continue;
    midpoint[edge_key(E(e, 0), E(e, 1), N)] = int32_t(s.pairs.size());
    s.pairs.emplace_back(E(e, 0), E(e, 1));
  }
  const int S = int(s.pairs.size());
  s.V.resize(S, 3);
  s.W.resize(S, c.body_weights.cols());
  s.mask.resize(size_t(S));
  s.body.resize(size_t(S));
  for (int v = 0; v < S; ++v) {
    const int a = s.pairs[size_t(v)].x(), b = s.pairs[size_t(v)].y();
    if (a == b) {
      s.V.row(v) = c.mesh.V.row(a);
      s.W.row(v) = c.body_weights.row(a);
    } else {
      s.V.row(v) = 0.5f * (c.mesh.V.row(a) + c.mesh.V.row(b));
      s.W.row(v) = 0.5f * (c.body_weights.row(a) + c.body_weights.row(b));
    }
    s.mask[size_t(v)] = std::max(c.apparel_mask[size_t(a)], c.apparel_mask[size_t(b)]);
    s.body[size_t(v)] = a < body_vertices && b < body_vertices;
  }
  std::vector<Eigen::Vector3i> faces;
  for (int f = 0; f < c.mesh.num_faces(); ++f) {
    int32_t v[3], m[3];
    int count = 0;
    for (int k = 0; k < 3; ++k) v[k] = c.mesh.F(f, k);
    for (int k = 0; k < 3; ++k) {
      const auto it = midpoint.find(edge_key(v[k], v[(k + 1) % 3], N));
      m[k] = it == midpoint.end() ? -1 : it->second;  // m[k] on edge v[k] -> v[k + 1]
      count += m[k] >= 0;
    }
    if (count == 0) {
      faces.emplace_back(v[0], v[1], v[2]);
    } else if (count == 3) {
      faces.emplace_back(v[0], m[0], m[2]);
      faces.emplace_back(m[0], v[1], m[1]);
      faces.emplace_back(m[2], m[1], v[2]);
      faces.emplace_back(m[0], m[1], m[2]);
    } else {
      for (int r = 0; r < 3; ++r) {
        const int r1 = (r + 1) % 3, r2 = (r + 2) % 3;
        if (count == 1 && m[r] >= 0) {
          faces.emplace_back(v[r], m[r], v[r2]);
          faces.emplace_back(m[r], v[r1], v[r2]);
        } else if (count == 2 && m[r] >= 0 && m[r1] >= 0) {
          faces.emplace_back(v[r1], m[r1], m[r]);
          faces.emplace_back(v[r], m[r], m[r1]);
          faces.emplace_back(v[r], m[r1], v[r2]);
        }
      }
    }
  }
  s.F.resize(Eigen::Index(faces.size()), 3);
  for (size_t f = 0; f < faces.size(); ++f) s.F.row(Eigen::Index(f)) = faces[f].transpose();
  return s;
}

// How a piece of garment or apparel is cut and copied.
struct Strip {
  float reverse_offset = 0;  // the reverse side's offset along the rest normal
  float layer_offset = 0;    // the second layer's, 0: no layer
};

// Cuts one connected piece (its faces, in the open-parts mesh V, F) lengthwise into strips (`hair`, or a long
// narrow piece: `strip_width` wide) or panels (`panel_width`), by the faces' position across the length axis, or
// their angle around it when the piece wraps around it (tubes, skirt rings). Returns a strip per face, numbered
// from 0, and the count.
std::vector<int32_t> cut_piece(const std::vector<int32_t>& faces, const MatrixX3f& V, const MatrixX3i& F, bool hair,
                               const ArtistStyleOptions& o, Draws& draws, int& count, bool& strips_out) {
  std::vector<int32_t> vertices;
  for (const int32_t f : faces)
    for (int k = 0; k < 3; ++k) vertices.push_back(F(f, k));
  std::sort(vertices.begin(), vertices.end());
  vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const int32_t v : vertices) mean += V.row(v).transpose().cast<double>();
  mean /= double(vertices.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const int32_t v : vertices) {
    const Eigen::Vector3d d = V.row(v).transpose().cast<double>() - mean;
    cov += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> pca(cov);
  const bool elongated = pca.eigenvalues()(2) > 6.25 * pca.eigenvalues()(1);
  const bool strips = hair || elongated;
  strips_out = strips;
  const Eigen::Vector3d axis = elongated ? Eigen::Vector3d(pca.eigenvectors().col(2)) : Eigen::Vector3d::UnitY();
  // Centres of 12 slabs along the axis, so that a bent strand or sheet is measured from its own middle.
  constexpr int kSlabs = 12;
  double low = 1e30, high = -1e30;
  for (const int32_t v : vertices) {
    const double h = V.row(v).cast<double>().dot(axis.transpose());
    low = std::min(low, h), high = std::max(high, h);
  }
  const auto slab = [&](const Eigen::Vector3d& p) {
    const double t = (p.dot(axis) - low) / std::max(high - low, 1e-9);
    return std::clamp(int(t * kSlabs), 0, kSlabs - 1);
  };
  std::vector<Eigen::Vector3d> centre(kSlabs, Eigen::Vector3d::Zero());
  std::vector<int> in_slab(kSlabs, 0);
  for (const int32_t v : vertices) {
    const Eigen::Vector3d p = V.row(v).transpose().cast<double>();
    centre[size_t(slab(p))] += p, ++in_slab[size_t(slab(p))];
  }
  for (int k = 0; k < kSlabs; ++k)
    if (in_slab[size_t(k)]) centre[size_t(k)] /= in_slab[size_t(k)];
  for (int pass = 0; pass < 2; ++pass)  // empty slabs take a neighbour's centre
    for (int k = 0; k < kSlabs; ++k) {
      const int from = pass == 0 ? k - 1 : kSlabs - k;
      if (!in_slab[size_t(k)] && from >= 0 && from < kSlabs && in_slab[size_t(from)])
        centre[size_t(k)] = centre[size_t(from)], in_slab[size_t(k)] = 1;
    }
  const auto across = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d r = p - centre[size_t(slab(p))];
    return Eigen::Vector3d(r - r.dot(axis) * axis);
  };
  // Principal direction across the axis, and whether the piece wraps around it.
  Eigen::Matrix3d cross = Eigen::Matrix3d::Zero();
  double radius = 0;
  for (const int32_t v : vertices) {
    const Eigen::Vector3d r = across(V.row(v).transpose().cast<double>());
    cross += r * r.transpose(), radius += r.norm();
  }
  radius /= double(vertices.size());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> section(cross);
  const Eigen::Vector3d w1 = section.eigenvectors().col(2), w2 = axis.cross(w1);
  const bool round = section.eigenvalues()(2) < 6.25 * section.eigenvalues()(1);
  const float width = strips ? o.strip_width : o.panel_width;
  const double phase = draws.uniform();
  double s_low = 1e30, s_high = -1e30;
  for (const int32_t v : vertices) {
    const double s = across(V.row(v).transpose().cast<double>()).dot(w1);
    s_low = std::min(s_low, s), s_high = std::max(s_high, s);
  }
  const int K = round ? std::clamp(int(std::lround(2 * kPi * radius / width)), 2, 64)
                      : std::clamp(int(std::lround((s_high - s_low) / width)), 1, 64);
  std::vector<int32_t> strip(faces.size());
  std::vector<int32_t> number(size_t(K) + 1, -1);
  count = 0;
  for (size_t i = 0; i < faces.size(); ++i) {
    const int32_t f = faces[i];
    const Eigen::Vector3d q = (V.row(F(f, 0)) + V.row(F(f, 1)) + V.row(F(f, 2))).transpose().cast<double>() / 3.0;
    const Eigen::Vector3d r = across(q);
    int k = 0;
    if (round) {
      const double turn = std::atan2(r.dot(w2), r.dot(w1)) / (2 * kPi) + 0.5 + phase;
      k = int((turn - std::floor(turn)) * K) % K;
    } else {
      k = std::clamp(int(std::floor((r.dot(w1) - s_low) / std::max(s_high - s_low, 1e-9) * K + phase)), 0, K);
    }
    if (number[size_t(k)] < 0) number[size_t(k)] = count++;
    strip[i] = number[size_t(k)];
  }
  return strip;
}

// An offset in [low, high] on a grid of kOffsetStep from low: two strips' reverse sides (or layers) at one source
// vertex either coincide exactly or lie a step apart, never within kCoincidentTolerance without being one point.
constexpr float kOffsetStep = 2.5e-4f;
float offset_draw(float low, float high, Draws& draws) {
  const int steps = int(std::floor((high - low) / kOffsetStep + 1e-3f)) + 1;
  return std::min(high, low + kOffsetStep * float(std::min(steps - 1, int(draws.uniform() * steps))));
}

// The remake at one subdivision level.
ArtistStyleCharacter remake(const CharacterData& c, int body_vertices, int64_t splits, const ArtistStyleOptions& o) {
  const auto& names = canonical_joint_names();
  const int head = int(std::find(names.begin(), names.end(), "head") - names.begin());
  const int neck = int(std::find(names.begin(), names.end(), "neck") - names.begin());
  const Subdivided sub = subdivide(c, body_vertices, splits);
  const int S = int(sub.pairs.size());

  // Open parts of the body, on the subdivided mesh reordered body first (open_parts_character's layout).
  std::vector<int32_t> order;  // open-parts input vertex -> subdivided vertex
  for (int v = 0; v < S; ++v)
    if (sub.body[size_t(v)]) order.push_back(v);
  const int Nb = int(order.size());
  for (int v = 0; v < S; ++v)
    if (!sub.body[size_t(v)]) order.push_back(v);
  std::vector<int32_t> position(static_cast<size_t>(S));
  for (int k = 0; k < S; ++k) position[size_t(order[size_t(k)])] = k;
  DressedCharacter dressed;
  dressed.mesh.V.resize(S, 3);
  dressed.body_weights.resize(S, sub.W.cols());
  dressed.apparel_mask.resize(size_t(S));
  for (int k = 0; k < S; ++k) {
    dressed.mesh.V.row(k) = sub.V.row(order[size_t(k)]);
    dressed.body_weights.row(k) = sub.W.row(order[size_t(k)]);
    dressed.apparel_mask[size_t(k)] = sub.mask[size_t(order[size_t(k)])];
  }
  dressed.mesh.F = sub.F;
  for (Eigen::Index f = 0; f < sub.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) dressed.mesh.F(f, k) = position[size_t(sub.F(f, k))];
  dressed.body.mesh.V = dressed.mesh.V.topRows(Nb);
  const OpenPartsCharacter open = open_parts_character(dressed, o.open_parts);
  const int P = open.mesh.num_vertices();
  const MatrixX3f normals = vertex_normals(sub.V, sub.F);
  // Per open-parts vertex: its subdivided source and offset (the inset of a borrowed seam ring).
  std::vector<int32_t> source(static_cast<size_t>(P));
  std::vector<float> inset(static_cast<size_t>(P), 0.0f);
  for (int v = 0; v < P; ++v) {
    const int32_t s = open.source[size_t(v)] < 0 ? -1 : order[size_t(open.source[size_t(v)])];
    source[size_t(v)] = s;
    if (s >= 0 && o.open_parts.overlap_inset > 0 &&
        (open.mesh.V.row(v) - sub.V.row(s)).dot(normals.row(s)) < -0.5f * o.open_parts.overlap_inset)
      inset[size_t(v)] = -o.open_parts.overlap_inset;
  }

  // Patches: every body part (and the cap), and the strips and panels of every garment or apparel piece.
  Draws draws{std::mt19937_64(o.seed)};
  const int F = open.mesh.num_faces();
  std::vector<int32_t> patch(size_t(F), -1);
  std::vector<Strip> strips(size_t(open.num_parts));
  for (int f = 0; f < F; ++f)
    if (open.part[size_t(open.mesh.F(f, 0))] >= 0) patch[size_t(f)] = open.part[size_t(open.mesh.F(f, 0))];
  {
    DisjointSets pieces(P);
    for (int f = 0; f < F; ++f)
      if (patch[size_t(f)] < 0)
        for (int k = 0; k < 2; ++k) pieces.unite(open.mesh.F(f, k), open.mesh.F(f, k + 1));
    std::map<int32_t, std::vector<int32_t>> faces_of;  // piece (smallest vertex) -> faces
    for (int f = 0; f < F; ++f)
      if (patch[size_t(f)] < 0) faces_of[pieces.find(open.mesh.F(f, 0))].push_back(f);
    for (const auto& [root, faces] : faces_of) {
      // Hair: a piece whose weights sum largest on the head or the neck.
      Eigen::RowVectorXf sum = Eigen::RowVectorXf::Zero(open.body_weights.cols());
      for (const int32_t f : faces)
        for (int k = 0; k < 3; ++k) sum += open.body_weights.row(open.mesh.F(f, k));
      Eigen::Index joint = 0;
      sum.maxCoeff(&joint);
      const bool hair = joint == head || joint == neck;
      int count = 0;
      bool narrow = false;
      const std::vector<int32_t> local = cut_piece(faces, open.mesh.V, open.mesh.F, hair, o, draws, count, narrow);
      const int first = int(strips.size());
      for (int k = 0; k < count; ++k) {
        Strip s;
        s.reverse_offset = offset_draw(o.back_offset_min, o.back_offset_max, draws);
        if (!narrow && draws.uniform() < o.layer_share)
          s.layer_offset = offset_draw(o.layer_offset_min, o.layer_offset_max, draws);
        strips.push_back(s);
      }
      for (size_t i = 0; i < faces.size(); ++i) patch[size_t(faces[i])] = first + local[i];
    }
  }

  // UV islands: breadth-first regions of about island_faces faces over the edges shared within a patch.
  std::unordered_map<int64_t, std::vector<int32_t>> edge_faces;
  for (int f = 0; f < F; ++f)
    for (int k = 0; k < 3; ++k) edge_faces[edge_key(open.mesh.F(f, k), open.mesh.F(f, (k + 1) % 3), P)].push_back(f);
  std::vector<int32_t> island(size_t(F), -1);
  int islands = 0;
  for (int seed = 0; seed < F; ++seed) {
    if (island[size_t(seed)] >= 0) continue;
    const int size = std::max(1, int(std::lround(o.island_faces * draws.uniform(0.5f, 1.5f))));
    std::deque<int32_t> queue{seed};
    island[size_t(seed)] = islands;
    int taken = 1;
    while (!queue.empty() && taken < size) {
      const int32_t f = queue.front();
      queue.pop_front();
      for (int k = 0; k < 3 && taken < size; ++k)
        for (const int32_t g : edge_faces[edge_key(open.mesh.F(f, k), open.mesh.F(f, (k + 1) % 3), P)]) {
          if (island[size_t(g)] >= 0 || patch[size_t(g)] != patch[size_t(f)] || taken >= size) continue;
          island[size_t(g)] = islands;
          queue.push_back(g);
          ++taken;
        }
    }
    ++islands;
  }

  // The remade surfaces: front faces, then the reverse sides of garment and apparel, then the layers; each island
  // with its own vertex copies.
  ArtistStyleCharacter out;
  out.num_strips = int(strips.size());
  std::unordered_map<int64_t, int32_t> copy;
  std::vector<int32_t> copy_of;  // remade vertex -> open-parts vertex
  std::vector<Eigen::Vector3i> faces;
  for (const ArtistSide side : {ArtistSide::kFront, ArtistSide::kReverse, ArtistSide::kLayer}) {
    for (int f = 0; f < F; ++f) {
      const int32_t p = patch[size_t(f)];
      const bool piece = p >= open.num_parts;
      float extra = 0;
      if (side == ArtistSide::kReverse) {
        if (!piece) continue;
        extra = strips[size_t(p)].reverse_offset;
      } else if (side == ArtistSide::kLayer) {
        if (!piece || strips[size_t(p)].layer_offset <= 0) continue;
        extra = strips[size_t(p)].layer_offset;
      }
      const int64_t group = int64_t(static_cast<int>(side)) * islands + island[size_t(f)];
      Eigen::Vector3i face;
      for (int k = 0; k < 3; ++k) {
        const int32_t v = open.mesh.F(f, k);
        const auto [it, added] = copy.try_emplace(group * P + v, int32_t(copy_of.size()));
        if (added) {
          copy_of.push_back(v);
          out.source.push_back(source[size_t(v)]);
          out.offset.push_back(inset[size_t(v)] + extra);
          out.joint.push_back(source[size_t(v)] < 0 ? head : -1);
          out.side.push_back(side);
          out.strip.push_back(p);
        }
        face[k] = it->second;
      }
      if (side == ArtistSide::kReverse) std::swap(face[1], face[2]);
      faces.push_back(face);
    }
  }

  const int M = int(copy_of.size());
  CharacterData& r = out.character;
  r.name = c.name;
  r.split = c.split;
  r.skeleton = c.skeleton;
  r.mesh.V.resize(M, 3);
  r.mesh.F.resize(Eigen::Index(faces.size()), 3);
  for (size_t f = 0; f < faces.size(); ++f) r.mesh.F.row(Eigen::Index(f)) = faces[f].transpose();
  r.apparel_mask.assign(size_t(M), 0);
  r.body_weights = MatrixXfR::Zero(M, c.body_weights.cols());
  out.source_pairs.resize(M, 2);
  out.source_weights = MatrixXfR::Zero(M, 2);
  for (int i = 0; i < M; ++i) {
    const int32_t s = out.source[size_t(i)];
    if (s < 0) {
      r.mesh.V.row(i) = open.mesh.V.row(copy_of[size_t(i)]);
      r.body_weights(i, head) = 1.0f;
      out.source_pairs.row(i) << -1, -1;
      continue;
    }
    r.mesh.V.row(i) = sub.V.row(s) + out.offset[size_t(i)] * normals.row(s);
    r.apparel_mask[size_t(i)] = sub.mask[size_t(s)];
    r.body_weights.row(i) = sub.W.row(s);
    const Eigen::Vector2i pair = sub.pairs[size_t(s)];
    out.source_pairs.row(i) = pair.transpose();
    out.source_weights.row(i) << (pair.x() == pair.y() ? 1.0f : 0.5f), (pair.x() == pair.y() ? 0.0f : 0.5f);
  }
  out.source_vertices = S;
  out.midpoints.resize(S - c.mesh.num_vertices(), 2);
  for (int v = c.mesh.num_vertices(); v < S; ++v)
    out.midpoints.row(v - c.mesh.num_vertices()) = sub.pairs[size_t(v)].transpose();
  out.subdivided_faces = sub.F;
  return out;
}

}  // namespace

// === Remake

ArtistStyleCharacter artist_style_character(const CharacterData& c, const ArtistStyleOptions& o) {
  AMT_CHECK(o.target_vertices == 0 || o.target_vertices >= 1000,
            "artist style: target vertices: expected 0 (no subdivision) or >= 1000, found ", o.target_vertices);
  AMT_CHECK(o.strip_width > 0 && std::isfinite(o.strip_width), "artist style: strip width: expected > 0 metres, found ",
            o.strip_width);
  AMT_CHECK(o.panel_width > 0 && std::isfinite(o.panel_width), "artist style: panel width: expected > 0 metres, found ",
            o.panel_width);
  AMT_CHECK(
      o.back_offset_min > kWeldTolerance && o.back_offset_min <= o.back_offset_max && std::isfinite(o.back_offset_max),
      "artist style: reverse side offset: expected ", kWeldTolerance, " < min <= max metres, found ", o.back_offset_min,
      " to ", o.back_offset_max);
  AMT_CHECK(o.layer_share >= 0 && o.layer_share <= 1, "artist style: layer share: expected in [0, 1], found ",
            o.layer_share);
  AMT_CHECK(o.layer_offset_min > o.back_offset_max && o.layer_offset_min <= o.layer_offset_max &&
                std::isfinite(o.layer_offset_max),
            "artist style: layer offset: expected ", o.back_offset_max,
            " (the reverse side's largest) < min <= max metres, found ", o.layer_offset_min, " to ",
            o.layer_offset_max);
  AMT_CHECK(o.island_faces >= 2, "artist style: island faces: expected >= 2, found ", o.island_faces);
  const auto& names = canonical_joint_names();
  AMT_CHECK(c.skeleton.names == std::vector<std::string>(names.begin(), names.end()) &&
                c.body_weights.cols() == int(names.size()),
            "artist style: ", c.name, ": expected the canonical skeleton's ", names.size(),
            " joints and weight columns, found ", c.skeleton.num_joints(), " joints and ", c.body_weights.cols(),
            " columns");
  const int N = c.mesh.num_vertices();
  AMT_CHECK(N > 0 && int(c.apparel_mask.size()) == N && c.body_weights.rows() == N, "artist style: ", c.name,
            ": expected a mesh with a mask and weights per vertex, found ", N, " vertices, ", c.apparel_mask.size(),
            " mask entries, ", c.body_weights.rows(), " weight rows");
  // The body: the run of leading vertices of the largest connected part (the builder's layout).
  int count = 0;
  const std::vector<int32_t> label = connected_components(N, unique_edges(c.mesh.F), &count);
  std::vector<int32_t> size(size_t(count), 0);
  for (const int32_t l : label) ++size[size_t(l)];
  const int32_t largest = int32_t(std::max_element(size.begin(), size.end()) - size.begin());
  int Nb = 0;
  while (Nb < N && label[size_t(Nb)] == largest) ++Nb;
  AMT_CHECK(Nb > 0, "artist style: ", c.name,
            ": expected the body's vertices first, found vertex 0 off the largest part");

  ArtistStyleCharacter out = remake(c, Nb, 0, o);
  if (o.target_vertices > 0) {
    // The remake's vertex count grows about in proportion to the source's: aim the splits by that ratio, twice.
    const int64_t edges = unique_edges(c.mesh.F).rows();
    int64_t splits = 0;
    for (int pass = 0; pass < 2; ++pass) {
      const int M = out.character.mesh.num_vertices();
      if (std::abs(M - o.target_vertices) <= 0.02 * o.target_vertices) break;
      const double ratio = double(M) / double(N + splits);
      const int64_t next = std::clamp<int64_t>(std::llround(o.target_vertices / ratio) - N, 0, edges);
      if (next == splits) break;
      splits = next;
      out = remake(c, Nb, splits, o);
    }
  }
  return out;
}

MatrixX3f remake_frame(const ArtistStyleCharacter& r, const MatrixX3f& x, const Transforms& joints) {
  const int N = r.source_vertices - int(r.midpoints.rows());
  const int J = r.character.skeleton.num_joints();
  AMT_CHECK(x.rows() == N, "artist style: frame: expected ", N, " source vertices, found ", x.rows());
  AMT_CHECK(int(joints.size()) == J, "artist style: frame: expected ", J, " joint transforms, found ", joints.size());
  MatrixX3f sub(r.source_vertices, 3);
  sub.topRows(N) = x;
  for (Eigen::Index m = 0; m < r.midpoints.rows(); ++m)
    sub.row(N + m) = 0.5f * (x.row(r.midpoints(m, 0)) + x.row(r.midpoints(m, 1)));
  const bool offsets = std::any_of(r.offset.begin(), r.offset.end(), [](float d) { return d != 0.0f; });
  const MatrixX3f normals = offsets ? vertex_normals(sub, r.subdivided_faces) : MatrixX3f();
  const int M = r.character.mesh.num_vertices();
  MatrixX3f out(M, 3);
  for (int i = 0; i < M; ++i) {
    const int32_t s = r.source[size_t(i)];
    if (s < 0) {
      const int j = r.joint[size_t(i)];
      const Transform34& T = joints[size_t(j)];
      const Eigen::Vector3f p =
          r.character.mesh.V.row(i).transpose() - r.character.skeleton.rest_joints.row(j).transpose();
      out.row(i) = (T.leftCols<3>() * p + T.col(3)).transpose();
    } else if (r.offset[size_t(i)] != 0.0f) {
      out.row(i) = sub.row(s) + r.offset[size_t(i)] * normals.row(s);
    } else {
      out.row(i) = sub.row(s);
    }
  }
  return out;
}

MatrixX3f remake_frames(const ArtistStyleCharacter& r, const MatrixX3f& frames, const Transforms& joints) {
  const int N = r.source_vertices - int(r.midpoints.rows());
  const int J = r.character.skeleton.num_joints();
  AMT_CHECK(N > 0 && frames.rows() % N == 0, "artist style: frames: expected a multiple of ", N,
            " source vertices, found ", frames.rows(), " rows");
  const int T = int(frames.rows() / N);
  AMT_CHECK(int(joints.size()) == T * J, "artist style: frames: expected ", T * J, " joint transforms for ", T,
            " frames, found ", joints.size());
  const int M = r.character.mesh.num_vertices();
  MatrixX3f out(Eigen::Index(T) * M, 3);
  for (int t = 0; t < T; ++t) {
    const Transforms pose(joints.begin() + ptrdiff_t(t) * J, joints.begin() + ptrdiff_t(t + 1) * J);
    out.middleRows(Eigen::Index(t) * M, M) = remake_frame(r, frames.middleRows(Eigen::Index(t) * N, N), pose);
  }
  return out;
}

// === What real models look like

MeshConstruction mesh_construction(const MatrixX3f& V, const MatrixX3i& F) {
  MeshConstruction m;
  m.vertices = int(V.rows());
  m.faces = int(F.rows());
  const MatrixX2i E = unique_edges(F);
  connected_components(m.vertices, E, &m.parts);
  const std::vector<int32_t> weld = weld_vertices(V, kCoincidentTolerance);
  std::vector<int32_t> copies(size_t(m.vertices), 0);
  for (const int32_t w : weld) ++copies[size_t(w)];
  int64_t coincident = 0;
  for (int i = 0; i < m.vertices; ++i) coincident += copies[size_t(weld[size_t(i)])] > 1;
  m.coincident_share = m.vertices > 0 ? double(coincident) / m.vertices : 0.0;
  DisjointSets welded(m.vertices);
  for (Eigen::Index e = 0; e < E.rows(); ++e) welded.unite(weld[size_t(E(e, 0))], weld[size_t(E(e, 1))]);
  std::vector<uint8_t> counted(size_t(m.vertices), 0);
  for (int i = 0; i < m.vertices; ++i) {
    const int32_t root = welded.find(weld[size_t(i)]);
    if (!counted[size_t(root)]) counted[size_t(root)] = 1, ++m.welded_parts;
  }
  return m;
}

// === Measures of falling apart

MatrixX2i coincident_pairs(const MatrixX3f& V, const MatrixX3i& F, float tolerance) {
  const std::vector<int32_t> weld = weld_vertices(V, tolerance);
  // Vertices on an open boundary: an undirected edge of exactly one face.
  std::unordered_map<int64_t, int> uses;
  const int64_t N = V.rows();
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) ++uses[edge_key(F(f, k), F(f, (k + 1) % 3), N)];
  std::vector<uint8_t> boundary(size_t(N), 0);
  for (const auto& [key, count] : uses)
    if (count == 1) boundary[size_t(key / N)] = boundary[size_t(key % N)] = 1;
  std::vector<int32_t> first(size_t(N), -1);  // per weld group: its smallest boundary vertex
  std::vector<Eigen::Vector2i> pairs;
  for (int32_t i = 0; i < int32_t(N); ++i) {
    if (!boundary[size_t(i)]) continue;
    int32_t& root = first[size_t(weld[size_t(i)])];
    if (root < 0)
      root = i;
    else
      pairs.emplace_back(root, i);
  }
  MatrixX2i out(Eigen::Index(pairs.size()), 2);
  for (size_t k = 0; k < pairs.size(); ++k) out.row(Eigen::Index(k)) = pairs[k].transpose();
  return out;
}

MatrixX2i apparel_edges(const MatrixX2i& E, const std::vector<uint8_t>& mask) {
  std::vector<Eigen::Index> keep;
  for (Eigen::Index e = 0; e < E.rows(); ++e)
    if (mask[size_t(E(e, 0))] || mask[size_t(E(e, 1))]) keep.push_back(e);
  MatrixX2i out(Eigen::Index(keep.size()), 2);
  for (size_t k = 0; k < keep.size(); ++k) out.row(Eigen::Index(k)) = E.row(keep[k]);
  return out;
}

namespace {
// The seam gap histogram: bin 0 below kFirstGapCm, then bins 1 % wide up to 1e4 cm.
constexpr double kFirstGapCm = 1e-4, kGapBinRatio = 1.01;
const int kGapBins = 2 + int(std::log(1e8) / std::log(kGapBinRatio));
int gap_bin(double cm) {
  if (!std::isfinite(cm)) return kGapBins - 1;
  if (!(cm >= kFirstGapCm)) return 0;
  return std::min(kGapBins - 1, 1 + int(std::log(cm / kFirstGapCm) / std::log(kGapBinRatio)));
}
}  // namespace

SeparationAccumulator::SeparationAccumulator(MatrixX2i pairs, MatrixX2i edges, const MatrixX3f& rest)
    : pairs_(std::move(pairs)),
      edges_(std::move(edges)),
      histogram_(size_t(kGapBins), 0),
      bin_max_cm_(size_t(kGapBins), 0.0) {
  if (rest.rows() == 0) return;
  rest_lengths_.resize(size_t(edges_.rows()));
  for (Eigen::Index e = 0; e < edges_.rows(); ++e)
    rest_lengths_[size_t(e)] = (rest.row(edges_(e, 0)) - rest.row(edges_(e, 1))).norm();
}

void SeparationAccumulator::begin_clip() {
  frame_els_sum_ = 0, frame_els_count_ = 0;
}

void SeparationAccumulator::add_frame(const MatrixX3f& pred, const MatrixX3f& gt) {
  double els = 0;
  int counted = 0;
  for (Eigen::Index e = 0; e < edges_.rows(); ++e) {
    const double l_gt = (gt.row(edges_(e, 0)) - gt.row(edges_(e, 1))).norm();
    if (!(l_gt > 1e-9)) continue;
    const double ratio = (pred.row(edges_(e, 0)) - pred.row(edges_(e, 1))).norm() / l_gt;
    const double off = std::abs(ratio - 1.0);
    torn_ += !(off <= 0.5);
    els += 1.0 - off;
    ++counted;
    if (rest_lengths_.empty() || !(rest_lengths_[size_t(e)] > 1e-9)) continue;
    const double l_rest = rest_lengths_[size_t(e)];
    const bool gt_deformed = !(std::abs(l_gt / l_rest - 1.0) <= 0.5);
    rest_torn_ += !(std::abs((pred.row(edges_(e, 0)) - pred.row(edges_(e, 1))).norm() / l_rest - 1.0) <= 0.5);
    gt_rest_torn_ += gt_deformed;
    torn_gt_deformed_ += gt_deformed && !(off <= 0.5);
    ++rest_edge_frames_;
  }
  edge_frames_ += counted;
  if (counted > 0) frame_els_sum_ += els / counted, ++frame_els_count_;
  for (Eigen::Index p = 0; p < pairs_.rows(); ++p) {
    double cm = 100.0 * std::max(0.0f, (pred.row(pairs_(p, 0)) - pred.row(pairs_(p, 1))).norm() -
                                           (gt.row(pairs_(p, 0)) - gt.row(pairs_(p, 1))).norm());
    if (!std::isfinite(cm)) cm = std::numeric_limits<double>::infinity();  // a NaN prediction is torn apart
    const int bin = gap_bin(cm);
    ++histogram_[size_t(bin)];
    bin_max_cm_[size_t(bin)] = std::max(bin_max_cm_[size_t(bin)], cm);
    max_gap_cm_ = std::max(max_gap_cm_, cm);
  }
  pair_frames_ += pairs_.rows();
}

void SeparationAccumulator::end_clip() {
  if (frame_els_count_ > 0) clip_els_sum_ += frame_els_sum_ / frame_els_count_, ++clip_els_count_;
  frame_els_sum_ = 0, frame_els_count_ = 0;
}

SeparationScores SeparationAccumulator::result() const {
  SeparationScores s;
  const double nan = std::nan("");
  s.pairs = pairs_.rows();
  s.edge_frames = edge_frames_;
  s.pair_frames = pair_frames_;
  s.tearing = edge_frames_ > 0 ? double(torn_) / double(edge_frames_) : nan;
  const double rest_frames = double(rest_edge_frames_);
  s.rest_tearing = rest_edge_frames_ > 0 ? double(rest_torn_) / rest_frames : nan;
  s.ground_truth_rest_tearing = rest_edge_frames_ > 0 ? double(gt_rest_torn_) / rest_frames : nan;
  s.tearing_ground_truth_deformed = rest_edge_frames_ > 0 ? double(torn_gt_deformed_) / rest_frames : nan;
  s.apparel_els = clip_els_count_ > 0 ? clip_els_sum_ / clip_els_count_ : nan;
  s.seam_gap_p95_cm = s.seam_gap_max_cm = nan;
  if (pair_frames_ > 0) {
    // Nearest rank: the smallest gap that at least 95 % of the pair-frames do not exceed, as the largest gap
    // of its bin (exact when the bin holds one value; within 1 % otherwise).
    const int64_t rank = int64_t(std::ceil(0.95 * double(pair_frames_)));
    int64_t seen = 0;
    for (int b = 0; b < kGapBins; ++b) {
      seen += histogram_[size_t(b)];
      if (seen >= rank) {
        s.seam_gap_p95_cm = bin_max_cm_[size_t(b)];
        break;
      }
    }
    s.seam_gap_max_cm = max_gap_cm_;
  }
  return s;
}

}  // namespace amt
