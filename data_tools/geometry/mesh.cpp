#include "data_tools/geometry/mesh.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "data_tools/geometry/error.h"

namespace amt {

void validate_mesh(const TriMesh& mesh, const std::string& source) {
  AMT_CHECK(mesh.V.rows() > 0, source, ": vertices: expected at least 1 vertex, found an empty mesh");
  AMT_CHECK(mesh.F.rows() > 0, source, ": faces: expected at least 1 triangle, found none");
  for (Eigen::Index i = 0; i < mesh.V.rows(); ++i) {
    AMT_CHECK(mesh.V.row(i).allFinite(), source, ": vertices: expected finite values, found ", mesh.V(i, 0), " ",
              mesh.V(i, 1), " ", mesh.V(i, 2), " at vertex ", i);
  }
  const auto n = mesh.V.rows();
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int32_t v = mesh.F(f, k);
      AMT_CHECK(v >= 0 && v < n, source, ": faces: expected vertex indices in [0, ", n, "), found ", v, " in face ", f);
    }
  }
  check_plausible_extent(mesh, source);
}

namespace {

float median_of(std::vector<float>& values) {
  if (values.empty()) return 0.0f;
  auto mid = values.begin() + std::ptrdiff_t(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

}  // namespace

void check_plausible_extent(const TriMesh& mesh, const std::string& source) {
  const Eigen::Index n = mesh.V.rows();
  for (Eigen::Index i = 0; i < n; ++i) {
    AMT_CHECK(mesh.V.row(i).cwiseAbs().maxCoeff() <= kMaxCoordinate, source, ": vertices: expected coordinates within ",
              kMaxCoordinate, " of the origin, found ", mesh.V(i, 0), " ", mesh.V(i, 1), " ", mesh.V(i, 2), " at vertex ", i);
  }
  // Medians, not means or a bounding box: one absurd vertex must not move the yardstick it is judged by.
  Eigen::Vector3f centre;
  std::vector<float> values(static_cast<size_t>(n));
  for (int c = 0; c < 3; ++c) {
    for (Eigen::Index i = 0; i < n; ++i) values[size_t(i)] = mesh.V(i, c);
    centre[c] = median_of(values);
  }
  values.clear();
  values.reserve(size_t(mesh.F.rows()) * 3);
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int32_t a = mesh.F(f, k), b = mesh.F(f, (k + 1) % 3);
      if (a >= 0 && a < n && b >= 0 && b < n) values.push_back((mesh.V.row(a) - mesh.V.row(b)).norm());
    }
  }
  const float bound = kMaxEdgeLengths * median_of(values);
  if (!(bound > 0.0f)) return;
  for (Eigen::Index i = 0; i < n; ++i) {
    const float r = (mesh.V.row(i).transpose() - centre).norm();
    AMT_CHECK(r <= bound, source, ": vertices: expected positions within ", kMaxEdgeLengths,
              " median edge lengths (", bound, ") of the mesh's centre, found ", mesh.V(i, 0), " ", mesh.V(i, 1), " ",
              mesh.V(i, 2), " at vertex ", i, " (", r, " from the centre)");
  }
}

TriMesh submesh(const MatrixX3f& V, const MatrixX3i& F, const std::vector<int32_t>& ids) {
  std::vector<int32_t> index(static_cast<size_t>(V.rows()), -1);
  TriMesh out;
  out.V.resize(static_cast<Eigen::Index>(ids.size()), 3);
  for (size_t i = 0; i < ids.size(); ++i) {
    AMT_CHECK(ids[i] >= 0 && ids[i] < V.rows(), "submesh: vertex ids: expected indices in [0, ", V.rows(), "), found ",
              ids[i]);
    index[static_cast<size_t>(ids[i])] = static_cast<int32_t>(i);
    out.V.row(static_cast<Eigen::Index>(i)) = V.row(ids[i]);
  }
  std::vector<int32_t> faces;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const int32_t a = index[F(f, 0)], b = index[F(f, 1)], d = index[F(f, 2)];
    if (a >= 0 && b >= 0 && d >= 0) faces.insert(faces.end(), {a, b, d});
  }
  out.F = Eigen::Map<const MatrixX3i>(faces.data(), static_cast<Eigen::Index>(faces.size() / 3), 3);
  return out;
}

MatrixX2i unique_edges(const MatrixX3i& F) {
  std::vector<std::pair<int32_t, int32_t>> edges;
  edges.reserve(static_cast<size_t>(F.rows()) * 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      int32_t a = F(f, k), b = F(f, (k + 1) % 3);
      if (a == b) continue;  // degenerate face side
      if (a > b) std::swap(a, b);
      edges.emplace_back(a, b);
    }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  MatrixX2i E(static_cast<Eigen::Index>(edges.size()), 2);
  for (size_t e = 0; e < edges.size(); ++e) {
    E(static_cast<Eigen::Index>(e), 0) = edges[e].first;
    E(static_cast<Eigen::Index>(e), 1) = edges[e].second;
  }
  return E;
}

namespace {

// The sides i -> j of the faces that no side j -> i balances, as many times as unbalanced: the
// boundary of the surface as a chain, empty for a closed surface.
std::vector<std::pair<int32_t, int32_t>> unbalanced_sides(const MatrixX3i& F) {
  // Each side i -> j counts +1 for the undirected edge (min, max) when i < j, -1 otherwise.
  std::vector<std::pair<std::pair<int32_t, int32_t>, int>> sides;
  sides.reserve(static_cast<size_t>(F.rows()) * 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int32_t a = F(f, k), b = F(f, (k + 1) % 3);
      if (a != b) sides.push_back({std::minmax(a, b), a < b ? 1 : -1});
    }
  }
  std::sort(sides.begin(), sides.end());
  std::vector<std::pair<int32_t, int32_t>> boundary;
  for (size_t i = 0; i < sides.size();) {
    int sum = 0;
    size_t j = i;
    for (; j < sides.size() && sides[j].first == sides[i].first; ++j) sum += sides[j].second;
    const auto [lo, hi] = sides[i].first;
    for (int k = 0; k < std::abs(sum); ++k) boundary.push_back(sum > 0 ? std::make_pair(lo, hi) : std::make_pair(hi, lo));
    i = j;
  }
  return boundary;
}

}  // namespace

bool is_closed_surface(const MatrixX3i& F) {
  return unbalanced_sides(F).empty();
}

HoleFill fill_holes(const MatrixX3i& F, int num_vertices) {
  const std::vector<std::pair<int32_t, int32_t>> boundary = unbalanced_sides(F);
  // Holes: connected groups of boundary sides (union-find over their vertices).
  std::vector<int32_t> parent(static_cast<size_t>(num_vertices));
  for (int32_t v = 0; v < num_vertices; ++v) parent[size_t(v)] = v;
  const auto root = [&parent](int32_t v) {
    while (parent[size_t(v)] != v) v = parent[size_t(v)] = parent[size_t(parent[size_t(v)])];
    return v;
  };
  for (const auto& [a, b] : boundary) {
    AMT_CHECK(a >= 0 && a < num_vertices && b >= 0 && b < num_vertices, "fill_holes: faces: expected indices in [0, ",
              num_vertices, "), found ", std::max(a, b));
    parent[size_t(root(a))] = root(b);
  }
  HoleFill fill;
  std::vector<int32_t> hole_of(static_cast<size_t>(num_vertices), -1);
  for (const auto& [a, b] : boundary) {
    for (const int32_t v : {a, b}) {
      int32_t& h = hole_of[size_t(root(v))];
      if (h < 0) h = int32_t(fill.holes.size()), fill.holes.emplace_back();
    }
  }
  std::vector<uint8_t> listed(static_cast<size_t>(num_vertices), 0);
  fill.faces.resize(Eigen::Index(boundary.size()), 3);
  for (size_t e = 0; e < boundary.size(); ++e) {
    const auto [a, b] = boundary[e];
    const int32_t h = hole_of[size_t(root(a))];
    fill.faces.row(Eigen::Index(e)) << b, a, num_vertices + h;  // the side b -> a balances a -> b
    for (const int32_t v : {a, b}) {
      if (!listed[size_t(v)]) listed[size_t(v)] = 1, fill.holes[size_t(h)].push_back(v);
    }
  }
  return fill;
}

Adjacency vertex_adjacency(int num_vertices, const MatrixX2i& E) {
  Adjacency adj;
  adj.offsets.assign(static_cast<size_t>(num_vertices) + 1, 0);
  for (Eigen::Index e = 0; e < E.rows(); ++e) {
    ++adj.offsets[E(e, 0) + 1];
    ++adj.offsets[E(e, 1) + 1];
  }
  std::partial_sum(adj.offsets.begin(), adj.offsets.end(), adj.offsets.begin());
  adj.neighbors.resize(static_cast<size_t>(adj.offsets.back()));
  std::vector<int32_t> fill(adj.offsets.begin(), adj.offsets.end() - 1);
  for (Eigen::Index e = 0; e < E.rows(); ++e) {
    adj.neighbors[fill[E(e, 0)]++] = E(e, 1);
    adj.neighbors[fill[E(e, 1)]++] = E(e, 0);
  }
  for (int i = 0; i < num_vertices; ++i) {
    std::sort(adj.neighbors.begin() + adj.offsets[i], adj.neighbors.begin() + adj.offsets[i + 1]);
  }
  return adj;
}

DisjointSets::DisjointSets(int count) : parent_(static_cast<size_t>(count)), sets_(count) {
  std::iota(parent_.begin(), parent_.end(), 0);
}

int32_t DisjointSets::find(int32_t x) {
  while (parent_[x] != x) {
    parent_[x] = parent_[parent_[x]];
    x = parent_[x];
  }
  return x;
}

bool DisjointSets::unite(int32_t a, int32_t b) {
  a = find(a);
  b = find(b);
  if (a == b) return false;
  parent_[std::max(a, b)] = std::min(a, b);
  --sets_;
  return true;
}

std::vector<int32_t> connected_components(int num_vertices, const MatrixX2i& E, int* count) {
  DisjointSets sets(num_vertices);
  for (Eigen::Index e = 0; e < E.rows(); ++e) sets.unite(E(e, 0), E(e, 1));
  std::vector<int32_t> label(num_vertices, -1);
  int next = 0;
  for (int i = 0; i < num_vertices; ++i) {
    const int r = sets.find(i);
    if (label[r] < 0) label[r] = next++;  // r <= i: the representative is labelled first
    label[i] = label[r];
  }
  if (count) *count = next;
  return label;
}

MatrixX3f vertex_normals(const MatrixX3f& V, const MatrixX3i& F) {
  MatrixX3f N = MatrixX3f::Zero(V.rows(), 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const Eigen::Vector3f a = V.row(F(f, 0)), b = V.row(F(f, 1)), c = V.row(F(f, 2));
    const Eigen::Vector3f n = (b - a).cross(c - a);  // length = 2 * area: area weighting
    for (int k = 0; k < 3; ++k) N.row(F(f, k)) += n.transpose();
  }
  for (Eigen::Index i = 0; i < N.rows(); ++i) {
    const float len = N.row(i).norm();
    if (len > 0) N.row(i) /= len;
  }
  return N;
}

Eigen::VectorXf edge_lengths(const MatrixX3f& V, const MatrixX2i& E) {
  Eigen::VectorXf L(E.rows());
  for (Eigen::Index e = 0; e < E.rows(); ++e) L[e] = (V.row(E(e, 0)) - V.row(E(e, 1))).norm();
  return L;
}

}  // namespace amt
