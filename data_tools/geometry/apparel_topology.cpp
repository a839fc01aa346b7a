#include "data_tools/geometry/apparel_topology.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <unordered_map>
#include <utility>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/geodesic.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/segmentation_features.h"

namespace amt {
namespace {

// Unique undirected edges (i < j) of a list of pairs, sorted.
MatrixX2i unique_pairs(std::vector<std::pair<int32_t, int32_t>> pairs) {
  for (auto& [a, b] : pairs)
    if (a > b) std::swap(a, b);
  pairs.erase(std::remove_if(pairs.begin(), pairs.end(), [](const auto& p) { return p.first == p.second; }),
              pairs.end());
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  MatrixX2i E(static_cast<Eigen::Index>(pairs.size()), 2);
  for (size_t k = 0; k < pairs.size(); ++k)
    E(Eigen::Index(k), 0) = pairs[k].first, E(Eigen::Index(k), 1) = pairs[k].second;
  return E;
}

std::vector<std::pair<int32_t, int32_t>> pairs_of(const MatrixX2i& E) {
  std::vector<std::pair<int32_t, int32_t>> out(static_cast<size_t>(E.rows()));
  for (Eigen::Index k = 0; k < E.rows(); ++k) out[size_t(k)] = {E(k, 0), E(k, 1)};
  return out;
}

// Each vertex's smallest copy on its own side: the smallest vertex of its weld group (weld, from weld_vertices)
// whose side(i) is the same as its own. A group that straddles body and apparel splits in two, each side still
// one point: were the copies of a side tied only through a representative on the other side, they would not be
// tied at all and could part.
template <typename Side>
std::vector<int32_t> smallest_same_side(const std::vector<int32_t>& weld, Side side) {
  std::vector<int32_t> first[2] = {std::vector<int32_t>(weld.size(), -1), std::vector<int32_t>(weld.size(), -1)};
  std::vector<int32_t> out(weld.size());
  for (size_t i = 0; i < weld.size(); ++i) {
    int32_t& f = first[side(i) ? 1 : 0][size_t(weld[i])];
    if (f < 0) f = int32_t(i);
    out[i] = f;
  }
  return out;
}

int count_parts(int N, const std::vector<std::pair<int32_t, int32_t>>& pairs) {
  int count = 0;
  connected_components(N, unique_pairs(pairs), &count);
  return count;
}

}  // namespace

LinkedTopology linked_topology(const MatrixX3f& V, const MatrixX3i& F, const std::vector<uint8_t>& apparel_mask,
                               const TopologyOptions& options) {
  AMT_CHECK(std::isfinite(options.weld_tolerance) && options.weld_tolerance >= 0,
            "linked topology: weld tolerance: expected >= 0 metres, found ", options.weld_tolerance);
  AMT_CHECK(std::isfinite(options.proximity_radius) && options.proximity_radius >= 0,
            "linked topology: proximity radius: expected >= 0 metres, found ", options.proximity_radius);
  AMT_CHECK(options.proximity_links >= 0, "linked topology: proximity links: expected >= 0, found ",
            options.proximity_links);
  const int N = static_cast<int>(V.rows());
  AMT_CHECK(apparel_mask.empty() || apparel_mask.size() == size_t(N), "linked topology: apparel mask: expected ", N,
            " entries (one per vertex), found ", apparel_mask.size());
  const auto apparel = [&](int i) { return apparel_mask.empty() || apparel_mask[size_t(i)] != 0; };
  LinkedTopology out;
  std::vector<std::pair<int32_t, int32_t>> pairs = pairs_of(unique_edges(F));
  out.parts = count_parts(N, pairs);

  // Seam links: every vertex to the smallest vertex of its weld group on its side of the mask; a vertex whose
  // group's smallest vertex is on the other side counts as a refused link.
  out.weld = weld_vertices(V, options.weld_tolerance);
  const std::vector<int32_t> same = smallest_same_side(out.weld, [&](size_t i) { return apparel(int(i)); });
  for (int i = 0; i < N; ++i) {
    const int r = out.weld[size_t(i)];
    if (r == i) continue;
    if (apparel(i) != apparel(r)) ++out.refused_links;
    if (same[size_t(i)] == i) continue;
    pairs.emplace_back(same[size_t(i)], i);
    ++out.seam_links;
  }
  int welded_count = 0;
  const std::vector<int32_t> welded_part = connected_components(N, unique_pairs(pairs), &welded_count);
  out.welded_parts = welded_count;

  // Proximity links: from each apparel vertex to its nearest apparel vertex of each other welded part within
  // the radius (a hash grid of cell = radius), at most options.proximity_links of them, nearest parts first.
  const float radius = options.proximity_radius;
  if (radius > 0 && options.proximity_links > 0) {
    const auto key = [](int64_t x, int64_t y, int64_t z) { return (x * 73856093) ^ (y * 19349663) ^ (z * 83492791); };
    std::unordered_map<int64_t, std::vector<int32_t>> grid;
    std::vector<Eigen::Vector3i> cell(static_cast<size_t>(N));
    for (int i = 0; i < N; ++i) {
      if (!apparel(i)) continue;
      for (int k = 0; k < 3; ++k) cell[size_t(i)][k] = static_cast<int>(std::floor(V(i, k) / radius));
      grid[key(cell[size_t(i)].x(), cell[size_t(i)].y(), cell[size_t(i)].z())].push_back(i);
    }
    const float r2 = radius * radius;
    std::vector<std::pair<float, int32_t>> best;  // per other part: (squared distance, vertex)
    std::unordered_map<int32_t, size_t> slot;     // part -> index in best
    for (int i = 0; i < N; ++i) {
      if (!apparel(i)) continue;
      best.clear();
      slot.clear();
      const Eigen::Vector3i c = cell[size_t(i)];
      for (int dx = -1; dx <= 1; ++dx)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dz = -1; dz <= 1; ++dz) {
            const auto it = grid.find(key(c.x() + dx, c.y() + dy, c.z() + dz));
            if (it == grid.end()) continue;
            for (const int32_t j : it->second) {
              const int32_t p = welded_part[size_t(j)];
              if (p == welded_part[size_t(i)]) continue;
              const float d2 = (V.row(i) - V.row(j)).squaredNorm();
              if (d2 > r2) continue;
              const auto [at, fresh] = slot.emplace(p, best.size());
              if (fresh) {
                best.emplace_back(d2, j);
              } else if (std::make_pair(d2, j) < best[at->second]) {
                best[at->second] = {d2, j};
              }
            }
          }
      std::sort(best.begin(), best.end());
      const size_t keep = std::min(best.size(), static_cast<size_t>(options.proximity_links));
      for (size_t k = 0; k < keep; ++k) pairs.emplace_back(i, best[k].second);
    }
  }
  out.edges = unique_pairs(std::move(pairs));
  // A link is a proximity link when its ends lie in different welded parts.
  for (Eigen::Index k = 0; k < out.edges.rows(); ++k)
    if (welded_part[size_t(out.edges(k, 0))] != welded_part[size_t(out.edges(k, 1))]) ++out.proximity_links;
  int linked = 0;
  connected_components(N, out.edges, &linked);
  out.linked_parts = linked;
  return out;
}

std::vector<uint8_t> weld_consistent_mask(const std::vector<uint8_t>& mask, const std::vector<int32_t>& weld,
                                          int* changed) {
  AMT_CHECK(mask.size() == weld.size(), "weld-consistent mask: expected ", weld.size(), " mask entries, found ",
            mask.size());
  std::vector<uint8_t> out(mask.size());
  int count = 0;
  for (size_t i = 0; i < mask.size(); ++i) {
    out[i] = mask[size_t(weld[i])];
    count += out[i] != mask[i];
  }
  if (changed) *changed = count;
  return out;
}

std::vector<int32_t> canonical_copies(const std::vector<int32_t>& weld, const std::vector<uint8_t>& mask) {
  AMT_CHECK(mask.size() == weld.size(), "canonical copies: expected ", weld.size(), " mask entries, found ",
            mask.size());
  return smallest_same_side(weld, [&](size_t i) { return mask[i] != 0; });
}

MatrixXfR welded_geodesics(const MatrixX3f& V, const MatrixX3i& F, const MatrixX3f& joints,
                           const std::vector<int32_t>& ids, const std::vector<int32_t>& canon,
                           const std::string& what) {
  AMT_CHECK(canon.size() == size_t(V.rows()), "welded geodesics: expected ", V.rows(), " canonical copies, found ",
            canon.size());
  MatrixX3i F_w(F.rows(), 3);
  Eigen::Index kept = 0;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const int32_t a = canon[size_t(F(f, 0))], b = canon[size_t(F(f, 1))], c = canon[size_t(F(f, 2))];
    if (a == b || b == c || a == c) continue;
    F_w.row(kept++) << a, b, c;
  }
  F_w.conservativeResize(kept, 3);
  std::vector<int32_t> canonical;                                  // the canonical vertices among ids
  std::vector<int32_t> row_of(static_cast<size_t>(V.rows()), -1);  // their rows in `canonical`
  for (const int32_t i : ids) {
    if (canon[size_t(i)] != i) continue;
    row_of[size_t(i)] = static_cast<int32_t>(canonical.size());
    canonical.push_back(i);
  }
  const TriMesh part = submesh(V, F_w, canonical);
  AMT_CHECK(part.F.rows() > 0, what, ": faces: the skinning predictor needs faces between these vertices, found none (",
            part.V.rows(), " vertices)");
  const MatrixXfR G = geodesic_distances(part.V, part.F, joints);
  MatrixXfR out(static_cast<Eigen::Index>(ids.size()), G.cols());
  for (size_t k = 0; k < ids.size(); ++k) {
    const int32_t r = row_of[size_t(canon[size_t(ids[k])])];
    AMT_CHECK(r >= 0, what, ": weld: vertex ", ids[k], " welds to vertex ", canon[size_t(ids[k])],
              ", which is not among these vertices");
    out.row(Eigen::Index(k)) = G.row(r);
  }
  return out;
}

ApparelHandles apparel_handles(const MatrixX3f& V, const MatrixX2i& edges, const std::vector<int32_t>& apparel,
                               const std::vector<float>& hang_distance, const HandleOptions& options) {
  AMT_CHECK(std::isfinite(options.spacing) && options.spacing > 0,
            "apparel handles: spacing: expected > 0 metres, found ", options.spacing);
  AMT_CHECK(std::isfinite(options.radius) && options.radius > options.spacing,
            "apparel handles: radius: expected more than the spacing (", options.spacing, " m), found ",
            options.radius);
  AMT_CHECK(options.max_handles >= 1, "apparel handles: max handles: expected >= 1, found ", options.max_handles);
  const int N_a = static_cast<int>(apparel.size());
  AMT_CHECK(hang_distance.size() == apparel.size(), "apparel handles: hang distances: expected ", N_a,
            " (one per apparel vertex), found ", hang_distance.size());
  ApparelHandles out;
  const int K = options.max_handles;
  out.vertex_handles.setZero(N_a, K);
  out.vertex_weights.setZero(N_a, K);
  out.handle_edges.resize(0, 2);
  if (N_a == 0) return out;

  // Apparel adjacency over the edges with both ends apparel.
  std::unordered_map<int32_t, int32_t> position;
  position.reserve(apparel.size() * 2);
  for (int i = 0; i < N_a; ++i) {
    AMT_CHECK(apparel[size_t(i)] >= 0 && apparel[size_t(i)] < V.rows(), "apparel handles: apparel vertex ",
              apparel[size_t(i)], " is not a vertex of the ", V.rows(), "-vertex mesh");
    position.emplace(apparel[size_t(i)], i);
  }
  std::vector<std::vector<std::pair<int32_t, float>>> adjacency(static_cast<size_t>(N_a));
  for (Eigen::Index k = 0; k < edges.rows(); ++k) {
    const auto a = position.find(edges(k, 0)), b = position.find(edges(k, 1));
    if (a == position.end() || b == position.end()) continue;
    const float l = (V.row(edges(k, 0)) - V.row(edges(k, 1))).norm();
    adjacency[size_t(a->second)].emplace_back(b->second, l);
    adjacency[size_t(b->second)].emplace_back(a->second, l);
  }
  for (auto& list : adjacency) std::sort(list.begin(), list.end());

  // Bounded Dijkstra from one vertex: visits (vertex, distance) with distance < limit, in order.
  std::vector<float> dist(static_cast<size_t>(N_a), std::numeric_limits<float>::infinity());
  std::vector<int32_t> touched;
  const auto search = [&](int32_t source, float limit, auto&& visit) {
    using Item = std::pair<float, int32_t>;
    std::priority_queue<Item, std::vector<Item>, std::greater<Item>> queue;
    dist[size_t(source)] = 0;
    touched.push_back(source);
    queue.emplace(0.0f, source);
    while (!queue.empty()) {
      const auto [d, i] = queue.top();
      queue.pop();
      if (d > dist[size_t(i)]) continue;
      visit(i, d);
      for (const auto& [j, l] : adjacency[size_t(i)]) {
        const float e = d + l;
        if (e < limit && e < dist[size_t(j)]) {
          if (!std::isfinite(dist[size_t(j)])) touched.push_back(j);
          dist[size_t(j)] = e;
          queue.emplace(e, j);
        }
      }
    }
    for (const int32_t i : touched) dist[size_t(i)] = std::numeric_limits<float>::infinity();
    touched.clear();
  };

  // Pick handles in order of the distance from where each piece hangs.
  std::vector<int32_t> order(static_cast<size_t>(N_a));
  for (int i = 0; i < N_a; ++i) order[size_t(i)] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](int32_t a, int32_t b) { return hang_distance[size_t(a)] < hang_distance[size_t(b)]; });
  std::vector<float> cover(static_cast<size_t>(N_a), std::numeric_limits<float>::infinity());
  for (const int32_t i : order) {
    if (cover[size_t(i)] < options.spacing) continue;
    out.handles.push_back(i);
    search(i, options.spacing, [&](int32_t j, float d) { cover[size_t(j)] = std::min(cover[size_t(j)], d); });
  }
  const int H = out.num_handles();

  // Weights from every handle within the radius; the handles each vertex sees give the handle graph.
  std::vector<std::vector<std::pair<float, int32_t>>> seen(static_cast<size_t>(N_a));
  std::vector<std::pair<int32_t, int32_t>> pairs;
  std::vector<int32_t> handle_of(static_cast<size_t>(N_a), -1);
  for (int h = 0; h < H; ++h) handle_of[size_t(out.handles[size_t(h)])] = h;
  for (int h = 0; h < H; ++h) {
    search(out.handles[size_t(h)], options.radius, [&](int32_t j, float d) {
      seen[size_t(j)].emplace_back(d, h);
      if (handle_of[size_t(j)] >= 0 && handle_of[size_t(j)] != h) pairs.emplace_back(h, handle_of[size_t(j)]);
    });
  }
  for (int i = 0; i < N_a; ++i) {
    auto& list = seen[size_t(i)];
    AMT_CHECK(!list.empty(), "apparel handles: apparel vertex ", apparel[size_t(i)],
              " is reached by no handle (internal error: every vertex is within the spacing of one)");
    std::sort(list.begin(), list.end());
    const int k_used = std::min<int>(K, static_cast<int>(list.size()));
    double total = 0;
    for (int k = 0; k < k_used; ++k) {
      const double s = list[size_t(k)].first / options.radius;
      const double w = (1 - s * s) * (1 - s * s);
      out.vertex_handles(i, k) = list[size_t(k)].second;
      out.vertex_weights(i, k) = static_cast<float>(w);
      total += w;
    }
    for (int k = 0; k < k_used; ++k) out.vertex_weights(i, k) = static_cast<float>(out.vertex_weights(i, k) / total);
    for (int k = k_used; k < K; ++k) out.vertex_handles(i, k) = out.vertex_handles(i, 0);
    for (int a = 0; a < k_used; ++a)
      for (int b = a + 1; b < k_used; ++b) pairs.emplace_back(out.vertex_handles(i, a), out.vertex_handles(i, b));
  }
  out.handle_edges = unique_pairs(std::move(pairs));
  return out;
}

}  // namespace amt

// === The rig's own bones as handles

namespace amt {

ApparelBones select_apparel_bones(
    const std::vector<std::string>& names, const MatrixX3f& heads, const std::vector<int32_t>& parents,
    const Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& indices, const MatrixXfR& weights,
    const std::vector<uint8_t>& keep, const MatrixXfR& response) {
  const int B = static_cast<int>(names.size());
  AMT_CHECK(response.rows() == 0 || (response.rows() == B && response.cols() == kRigResponseChannels),
            "apparel bones: response: expected (", B, ", ", kRigResponseChannels, ") or none, found (", response.rows(),
            ", ", response.cols(), ")");
  AMT_CHECK(heads.rows() == B && static_cast<int>(parents.size()) == B && static_cast<int>(keep.size()) == B,
            "apparel bones: expected ", B, " heads, parents and flags, found ", heads.rows(), ", ", parents.size(),
            " and ", keep.size());
  AMT_CHECK(indices.rows() == weights.rows() && indices.cols() == weights.cols(),
            "apparel bones: expected skin indices and weights of one shape, found (", indices.rows(), ", ",
            indices.cols(), ") and (", weights.rows(), ", ", weights.cols(), ")");
  std::vector<int32_t> renumber(static_cast<size_t>(B), -1);
  ApparelBones out;
  for (int b = 0; b < B; ++b) {
    if (!keep[b]) continue;
    renumber[b] = out.num_bones();
    out.names.push_back(names[b]);
  }
  out.heads.resize(out.num_bones(), 3);
  for (int b = 0; b < B; ++b) {
    if (renumber[b] < 0) continue;
    out.heads.row(renumber[b]) = heads.row(b);
    int p = parents[b];
    for (int guard = 0; p >= 0 && p < B && renumber[p] < 0 && guard < B; ++guard) p = parents[p];
    out.parents.push_back(p >= 0 && p < B ? renumber[p] : -1);
  }
  out.indices = indices;
  out.weights = weights;
  for (Eigen::Index i = 0; i < indices.rows(); ++i) {
    for (Eigen::Index k = 0; k < indices.cols(); ++k) {
      const int b = indices(i, k);
      const bool kept = b >= 0 && b < B && renumber[b] >= 0 && weights(i, k) > 0.0f;
      out.indices(i, k) = kept ? renumber[b] : -1;
      if (!kept) out.weights(i, k) = 0.0f;
    }
  }
  if (response.rows() > 0) {
    out.response.resize(out.num_bones(), kRigResponseChannels);
    for (int b = 0; b < B; ++b)
      if (renumber[b] >= 0) out.response.row(renumber[b]) = response.row(b);
  }
  return out;
}

MatrixXfR vertex_response(const Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& indices,
                          const MatrixXfR& weights, const MatrixXfR& bone_response,
                          const std::vector<int32_t>& vertices) {
  AMT_CHECK(indices.rows() == weights.rows() && indices.cols() == weights.cols(),
            "vertex response: expected skin indices and weights of one shape, found (", indices.rows(), ", ",
            indices.cols(), ") and (", weights.rows(), ", ", weights.cols(), ")");
  AMT_CHECK(bone_response.cols() == kRigResponseChannels, "vertex response: expected ", kRigResponseChannels,
            " channels per bone, found ", bone_response.cols());
  const Eigen::Index B = bone_response.rows();
  MatrixXfR out = MatrixXfR::Zero(static_cast<Eigen::Index>(vertices.size()), kRigResponseChannels);
  for (size_t m = 0; m < vertices.size(); ++m) {
    const int32_t i = vertices[m];
    AMT_CHECK(i >= 0 && i < indices.rows(), "vertex response: vertex ", i, " out of range [0, ", indices.rows(), ")");
    float total = 0, moved = 0;
    Eigen::RowVectorXf sum = Eigen::RowVectorXf::Zero(kRigResponseChannels);
    for (Eigen::Index k = 0; k < indices.cols(); ++k) {
      const int32_t b = indices(i, k);
      const float w = weights(i, k);
      if (!(w > 0)) continue;
      total += w;
      if (b < 0 || b >= B || bone_response(b, 0) <= 0) continue;
      moved += w;
      sum += w * bone_response.row(b);
    }
    if (moved <= 0) continue;
    out.row(static_cast<Eigen::Index>(m)) = sum / moved;
    out(static_cast<Eigen::Index>(m), 0) = total > 0 ? moved / total : 0.0f;
  }
  return out;
}

ApparelHandles bone_handles(const MatrixX3f& V, const std::vector<int32_t>& apparel, const ApparelBones& bones,
                            int max_handles) {
  const int B = bones.num_bones(), N_a = static_cast<int>(apparel.size());
  AMT_CHECK(max_handles >= 1, "bone handles: max_handles: expected at least 1, found ", max_handles);
  AMT_CHECK(bones.heads.rows() == B && static_cast<int>(bones.parents.size()) == B,
            "bone handles: expected ", B, " heads and parents, found ", bones.heads.rows(), " and ", bones.parents.size());
  AMT_CHECK(bones.indices.rows() == V.rows() && bones.weights.rows() == V.rows() &&
                bones.indices.cols() == bones.weights.cols(),
            "bone handles: expected skin indices and weights of ", V.rows(), " vertices, found ", bones.indices.rows(),
            " and ", bones.weights.rows());
  for (const int32_t v : apparel) AMT_CHECK(v >= 0 && v < V.rows(), "bone handles: apparel vertex ", v, " out of range");
  // Each bone's heaviest apparel vertices, heaviest first, then nearest its head.
  struct Candidate {
    float weight, distance;
    int32_t row;
  };
  std::vector<std::vector<Candidate>> candidates(static_cast<size_t>(B));
  for (int r = 0; r < N_a; ++r) {
    const int v = apparel[r];
    for (Eigen::Index k = 0; k < bones.indices.cols(); ++k) {
      const int b = bones.indices(v, k);
      const float w = bones.weights(v, k);
      if (b < 0 || b >= B || !(w > 0.0f)) continue;
      candidates[b].push_back({w, (V.row(v) - bones.heads.row(b)).norm(), r});
    }
  }
  std::vector<int32_t> handle_of_bone(static_cast<size_t>(B), -1);
  std::vector<uint8_t> taken(static_cast<size_t>(N_a), 0);
  ApparelHandles out;
  for (int b = 0; b < B; ++b) {
    auto& list = candidates[b];
    if (list.empty()) continue;  // a bone that weighs no apparel vertex moves nothing
    std::sort(list.begin(), list.end(), [](const Candidate& x, const Candidate& y) {
      if (x.weight != y.weight) return x.weight > y.weight;
      if (x.distance != y.distance) return x.distance < y.distance;
      return x.row < y.row;
    });
    for (const Candidate& c : list) {
      if (taken[c.row]) continue;
      taken[c.row] = 1;
      handle_of_bone[b] = out.num_handles();
      out.handles.push_back(c.row);
      break;
    }
  }
  // A bone whose every vertex is already a handle joins the handle of the vertex it weighs most.
  std::vector<int32_t> handle_at_row(static_cast<size_t>(N_a), -1);
  for (int h = 0; h < out.num_handles(); ++h) handle_at_row[out.handles[h]] = h;
  for (int b = 0; b < B; ++b)
    if (handle_of_bone[b] < 0 && !candidates[b].empty()) handle_of_bone[b] = handle_at_row[candidates[b][0].row];
  const int H = out.num_handles();
  AMT_CHECK(H > 0, "bone handles: none of the ", B, " apparel bones weighs any of the ", N_a, " apparel vertices");

  const int K = max_handles;
  out.vertex_handles.setZero(N_a, K);
  out.vertex_weights.setZero(N_a, K);
  std::vector<std::pair<int32_t, int32_t>> edges;
  for (int r = 0; r < N_a; ++r) {
    const int v = apparel[r];
    std::vector<std::pair<float, int32_t>> w;  // (weight, handle), merged per handle
    for (Eigen::Index k = 0; k < bones.indices.cols(); ++k) {
      const int b = bones.indices(v, k);
      if (b < 0 || b >= B || !(bones.weights(v, k) > 0.0f)) continue;
      const int h = handle_of_bone[b];
      auto it = std::find_if(w.begin(), w.end(), [h](const auto& e) { return e.second == h; });
      if (it == w.end()) w.push_back({bones.weights(v, k), h});
      else it->first += bones.weights(v, k);
    }
    if (w.empty()) {  // outside the rig's apparel: the nearest handle at rest
      int best = 0;
      float best_d = std::numeric_limits<float>::infinity();
      for (int h = 0; h < H; ++h) {
        const float d = (V.row(v) - V.row(apparel[out.handles[h]])).squaredNorm();
        if (d < best_d) best_d = d, best = h;
      }
      w.push_back({1.0f, best});
    }
    std::stable_sort(w.begin(), w.end(), [](const auto& x, const auto& y) { return x.first > y.first; });
    if (static_cast<int>(w.size()) > K) w.resize(static_cast<size_t>(K));
    float sum = 0.0f;
    for (const auto& e : w) sum += e.first;
    for (int k = 0; k < K; ++k) {
      out.vertex_handles(r, k) = k < static_cast<int>(w.size()) ? w[k].second : w[0].second;
      out.vertex_weights(r, k) = k < static_cast<int>(w.size()) ? w[k].first / sum : 0.0f;
    }
    for (size_t a = 0; a < w.size(); ++a)
      for (size_t c = a + 1; c < w.size(); ++c)
        edges.push_back({std::min(w[a].second, w[c].second), std::max(w[a].second, w[c].second)});
  }
  for (int b = 0; b < B; ++b) {
    const int p = bones.parents[b];
    int hp = -1;
    for (int q = p, guard = 0; q >= 0 && q < B && guard < B; q = bones.parents[q], ++guard) {
      if (handle_of_bone[q] >= 0) {
        hp = handle_of_bone[q];
        break;
      }
    }
    const int hb = handle_of_bone[b];
    if (hb >= 0 && hp >= 0 && hb != hp) edges.push_back({std::min(hb, hp), std::max(hb, hp)});
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  edges.erase(std::remove_if(edges.begin(), edges.end(), [](const auto& e) { return e.first == e.second; }),
              edges.end());
  out.handle_edges.resize(static_cast<Eigen::Index>(edges.size()), 2);
  for (size_t e = 0; e < edges.size(); ++e) out.handle_edges.row(static_cast<Eigen::Index>(e)) << edges[e].first, edges[e].second;
  return out;
}

}  // namespace amt
