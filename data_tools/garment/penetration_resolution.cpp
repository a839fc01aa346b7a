#include "data_tools/garment/penetration_resolution.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/winding_number.h"

namespace amt {
namespace {

// How far out of a face's centroid, along its normal, the point is that decides whether the face is
// exposed (metres): beyond the rounding of the winding number next to the surface, within the gap a
// modeller leaves between overlapping parts (data_tools/builder/open_parts.h insets its seam rings 2 mm).
constexpr float kExposureOffset = 1e-3f;

}  // namespace

PenetrationResolver::PenetrationResolver(const MatrixX3i& F, const std::vector<uint8_t>& apparel_mask,
                                         PenetrationOptions options)
    : options_(options) {
  AMT_CHECK(options.margin >= 0 && std::isfinite(options.margin), "penetration: margin: expected >= 0, found ",
            options.margin);
  AMT_CHECK(options.smoothing_rings >= 0, "penetration: smoothing rings: expected >= 0, found ",
            options.smoothing_rings);
  const int N = int(apparel_mask.size());
  std::vector<int32_t> position(size_t(N), -1);
  for (int i = 0; i < N; ++i) {
    std::vector<int32_t>& part = apparel_mask[size_t(i)] ? apparel_ : body_;
    position[size_t(i)] = int32_t(part.size());
    part.push_back(i);
  }
  std::vector<Eigen::Vector3i> faces;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    bool body = true;
    for (int k = 0; k < 3; ++k) {
      AMT_CHECK(F(f, k) >= 0 && F(f, k) < N, "penetration: faces: expected indices in [0, ", N, "), found ", F(f, k));
      body = body && !apparel_mask[size_t(F(f, k))];
    }
    if (body) faces.emplace_back(position[size_t(F(f, 0))], position[size_t(F(f, 1))], position[size_t(F(f, 2))]);
  }
  // The body part with its holes (where apparel, or vertices the segmenter took for apparel, were cut
  // away) closed by fans to centres that follow the boundary: an inside test against a closed surface.
  body_faces_.resize(Eigen::Index(faces.size()), 3);
  for (size_t f = 0; f < faces.size(); ++f) body_faces_.row(Eigen::Index(f)) = faces[f].transpose();
  if (!faces.empty()) {
    HoleFill fill = fill_holes(body_faces_, int(body_.size()));
    holes_ = std::move(fill.holes);
    num_fan_faces_ = int(fill.faces.rows());
    body_faces_.conservativeResize(Eigen::Index(faces.size()) + fill.faces.rows(), 3);
    body_faces_.bottomRows(fill.faces.rows()) = fill.faces;
  }
  closed_body_ = !faces.empty() && is_closed_surface(body_faces_);
  // Apparel graph: mesh edges with both ends apparel, numbered by apparel position.
  const MatrixX2i E = unique_edges(F);
  std::vector<Eigen::Vector2i> inner;
  for (Eigen::Index e = 0; e < E.rows(); ++e) {
    if (apparel_mask[size_t(E(e, 0))] && apparel_mask[size_t(E(e, 1))]) {
      inner.emplace_back(position[size_t(E(e, 0))], position[size_t(E(e, 1))]);
    }
  }
  MatrixX2i Ea(Eigen::Index(inner.size()), 2);
  for (size_t e = 0; e < inner.size(); ++e) Ea.row(Eigen::Index(e)) = inner[e].transpose();
  apparel_adjacency_ = vertex_adjacency(int(apparel_.size()), Ea);
}

const WindingNumberTree& PenetrationResolver::posed_body(const MatrixX3f& V) {
  body_scratch_.resize(Eigen::Index(body_.size() + holes_.size()), 3);
  for (size_t k = 0; k < body_.size(); ++k) body_scratch_.row(Eigen::Index(k)) = V.row(body_[k]);
  for (size_t h = 0; h < holes_.size(); ++h) {
    Eigen::RowVector3f centre = Eigen::RowVector3f::Zero();
    for (const int32_t k : holes_[h]) centre += body_scratch_.row(k);
    body_scratch_.row(Eigen::Index(body_.size() + h)) = centre / float(holes_[h].size());
  }
  if (tree_) {
    tree_->refit(body_scratch_, false);  // the far field only when a query needs it (classify)
    return *tree_;
  }
  tree_ = std::make_unique<WindingNumberTree>(body_scratch_, body_faces_);
  // Exposed faces: the point kExposureOffset out of the centroid is not inside the body. Degenerate
  // faces count as exposed (they are never strictly nearer than their neighbours).
  const WindingNumberTree& tree = *tree_;
  exposed_.assign(size_t(body_faces_.rows()), 1);
#pragma omp parallel for schedule(dynamic, 256)
  for (Eigen::Index f = 0; f < body_faces_.rows(); ++f) {
    const Eigen::Vector3f a = body_scratch_.row(body_faces_(f, 0)), b = body_scratch_.row(body_faces_(f, 1)),
                          c = body_scratch_.row(body_faces_(f, 2));
    const Eigen::Vector3f n = (b - a).cross(c - a);
    const float length = n.norm();
    if (length > 0) exposed_[size_t(f)] = !tree.inside((a + b + c) / 3.0f + (kExposureOffset / length) * n);
  }
  // Fans across the body: a hole whose centre lies deep in the body (farther from the skin than half
  // the hole's mean radius) is not a patch of missing skin but a cut through a part (a seam loop, the two
  // rims of a band of skin dropped around a waist): its fan is no way out, whichever side it faces.
  const Eigen::Index num_real = body_faces_.rows() - Eigen::Index(num_fan_faces_);
  std::vector<uint8_t> real(size_t(body_faces_.rows()), 0);
  std::fill(real.begin(), real.begin() + num_real, 1);
  std::vector<uint8_t> across(holes_.size(), 0);
#pragma omp parallel for schedule(dynamic, 16)
  for (int h = 0; h < int(holes_.size()); ++h) {
    const Eigen::Vector3f centre = body_scratch_.row(Eigen::Index(body_.size()) + h).transpose();
    float radius = 0;
    for (const int32_t k : holes_[size_t(h)]) radius += (body_scratch_.row(k).transpose() - centre).norm();
    radius /= float(holes_[size_t(h)].size());
    across[size_t(h)] = tree.distance(centre, nullptr, &real) > 0.5f * radius;
  }
  for (Eigen::Index f = num_real; f < body_faces_.rows(); ++f) {
    const int32_t centre = body_faces_.row(f).maxCoeff();  // the fan's centre, numbered after body_
    if (across[size_t(centre) - body_.size()]) exposed_[size_t(f)] = 0;
  }
  if (std::find(exposed_.begin(), exposed_.end(), 1) == exposed_.end()) exposed_.assign(exposed_.size(), 1);
  return tree;
}

void PenetrationResolver::prepare(const MatrixX3f& V) {
  if (tree_ || apparel_.empty() || body_faces_.rows() == 0) return;
  AMT_CHECK(V.rows() == Eigen::Index(apparel_.size() + body_.size()), "penetration: expected ",
            apparel_.size() + body_.size(), " vertices, found ", V.rows());
  posed_body(V);
  if (options_.keep_rest_penetration) {
    classify(V);
    rest_inside_ = inside_;
  }
}

int PenetrationResolver::classify(const MatrixX3f& V) {
  const int Na = int(apparel_.size());
  // Carry-over is exact only on a closed body, where a verdict changes only by meeting the surface.
  const bool carry = closed_body_ && previous_.rows() == Na;
  previous_.resize(Na, 3);
  inside_.resize(size_t(Na));
  query_.clear();
  const WindingNumberTree& tree = *tree_;
  constexpr uint8_t kOpen = 2;  // no verdict carried over: queried below
  int carried = 0;
#pragma omp parallel for schedule(dynamic, 256) reduction(+ : carried)
  for (int k = 0; k < Na; ++k) {
    const Eigen::Vector3f p = V.row(apparel_[size_t(k)]).transpose();
    if (carry && tree.stays_clear(p, p - previous_.row(k).transpose())) {
      ++carried;
    } else {
      inside_[size_t(k)] = kOpen;
    }
    previous_.row(k) = p.transpose();
  }
  for (int k = 0; k < Na; ++k)
    if (inside_[size_t(k)] == kOpen) query_.push_back(k);
  if (query_.empty()) return carried;
  tree_->update_far_field();  // the expansions of this frame, for the winding numbers
#pragma omp parallel for schedule(dynamic, 64)
  for (int q = 0; q < int(query_.size()); ++q) {
    const int k = query_[size_t(q)];
    inside_[size_t(k)] = tree.inside(V.row(apparel_[size_t(k)]).transpose());
  }
  return carried;
}

Penetration PenetrationResolver::measure(const MatrixX3f& V, int* carried) {
  Penetration p;
  p.total = int(apparel_.size());
  if (carried) *carried = 0;
  if (apparel_.empty() || body_faces_.rows() == 0) return p;
  AMT_CHECK(V.rows() == Eigen::Index(apparel_.size() + body_.size()), "penetration: expected ",
            apparel_.size() + body_.size(), " vertices, found ", V.rows());
  const WindingNumberTree& tree = posed_body(V);
  const int c = classify(V);
  if (carried) *carried = c;
  std::vector<float> depth(apparel_.size(), 0.0f);
#pragma omp parallel for schedule(dynamic, 64)
  for (int k = 0; k < int(apparel_.size()); ++k) {
    if (inside_[size_t(k)]) depth[size_t(k)] = tree.distance(V.row(apparel_[size_t(k)]).transpose(), nullptr, &exposed_);
  }
  for (size_t k = 0; k < depth.size(); ++k) {  // summed in order: the same total on any thread count
    if (inside_[k]) ++p.inside, p.depth_sum_cm += 100.0 * double(depth[k]);
  }
  return p;
}

namespace {

// The runs of points at one position among n points (position(i) a 3-vector expression): `order` receives the points
// sorted by position, and the result the [first, end) ranges of `order` two or more long whose positions are equal
// bit for bit (the copies of a split seam are).
template <typename Position>
std::vector<std::pair<int, int>> coincident_runs(int n, const Position& position, std::vector<int>& order) {
  const auto key = [&](int i) {
    const Eigen::Vector3f p = position(i);
    return std::array<float, 3>{p(0), p(1), p(2)};
  };
  order.resize(size_t(n));
  for (int i = 0; i < n; ++i) order[size_t(i)] = i;
  std::sort(order.begin(), order.end(),
            [&](int x, int y) { return std::make_pair(key(x), x) < std::make_pair(key(y), y); });
  std::vector<std::pair<int, int>> runs;
  for (int i = 0; i < n;) {
    int j = i + 1;
    while (j < n && key(order[size_t(j)]) == key(order[size_t(i)])) ++j;
    if (j - i > 1) runs.emplace_back(i, j);
    i = j;
  }
  return runs;
}

// Every run of coincident points (coincident_runs) takes the mean of its members' moves (move(i) a reference).
template <typename Move>
void take_one_move(const std::vector<std::pair<int, int>>& runs, const std::vector<int>& order, const Move& move) {
  for (const auto& [first, end] : runs) {
    Eigen::Vector3f mean = Eigen::Vector3f::Zero();
    for (int i = first; i < end; ++i) mean += move(order[size_t(i)]);
    mean /= float(end - first);
    for (int i = first; i < end; ++i) move(order[size_t(i)]) = mean;
  }
}

}  // namespace

void PenetrationResolver::set_rig(
    const Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& vertex_handles,
    const MatrixXfR& vertex_weights, int num_handles) {
  AMT_CHECK(vertex_handles.rows() == Eigen::Index(apparel_.size()) && vertex_weights.rows() == vertex_handles.rows() &&
                vertex_weights.cols() == vertex_handles.cols(),
            "penetration: rig: expected ", apparel_.size(), " apparel rows of handles and weights, found ",
            vertex_handles.rows(), " x ", vertex_handles.cols(), " and ", vertex_weights.rows(), " x ",
            vertex_weights.cols());
  AMT_CHECK(num_handles > 0 && (vertex_handles.size() == 0 ||
                                (vertex_handles.minCoeff() >= 0 && vertex_handles.maxCoeff() < num_handles)),
            "penetration: rig: expected handle indices in [0, ", num_handles, ")");
  AMT_CHECK(vertex_weights.allFinite() && (vertex_weights.size() == 0 || vertex_weights.minCoeff() >= 0.0f),
            "penetration: rig: expected finite weights >= 0");
  rig_handles_ = vertex_handles;
  rig_weights_ = vertex_weights;
  rig_size_ = num_handles;
  rig_neighbors_.assign(size_t(num_handles), {});
  for (Eigen::Index k = 0; k < vertex_handles.rows(); ++k)
    for (Eigen::Index a = 0; a < vertex_handles.cols(); ++a)
      for (Eigen::Index b = 0; b < vertex_handles.cols(); ++b) {
        const int32_t x = vertex_handles(k, a), y = vertex_handles(k, b);
        if (x != y && vertex_weights(k, a) > 0.0f && vertex_weights(k, b) > 0.0f)
          rig_neighbors_[size_t(x)].push_back(y);
      }
  for (auto& n : rig_neighbors_) {
    std::sort(n.begin(), n.end());
    n.erase(std::unique(n.begin(), n.end()), n.end());
  }
}

std::vector<int> PenetrationResolver::spread_through_rig(const std::vector<uint8_t>& pushing,
                                                         std::vector<Eigen::Vector3f>& push) const {
  const int Na = int(apparel_.size());
  // Each handle the mean push of the pushing vertices it carries, by their weights on it.
  std::vector<Eigen::Vector3f> handle_push(size_t(rig_size_), Eigen::Vector3f::Zero());
  std::vector<float> handle_weight(size_t(rig_size_), 0.0f);
  for (int k = 0; k < Na; ++k) {
    if (!pushing[size_t(k)]) continue;
    for (Eigen::Index c = 0; c < rig_handles_.cols(); ++c) {
      const float w = rig_weights_(k, c);
      if (!(w > 0.0f)) continue;
      handle_push[size_t(rig_handles_(k, c))] += w * push[size_t(k)];
      handle_weight[size_t(rig_handles_(k, c))] += w;
    }
  }
  std::vector<int> ring(size_t(rig_size_), -1), frontier;
  for (int h = 0; h < rig_size_; ++h) {
    if (!(handle_weight[size_t(h)] > 0.0f)) continue;
    handle_push[size_t(h)] /= handle_weight[size_t(h)];
    ring[size_t(h)] = 0;
    frontier.push_back(h);
  }
  // Spread over the handles' graph (handles that share a vertex) as rings of vertices spread it without a rig.
  for (int r = 1; r <= options_.smoothing_rings && !frontier.empty(); ++r) {
    std::vector<int> next;
    for (int h : frontier)
      for (int n : rig_neighbors_[size_t(h)])
        if (ring[size_t(n)] == -1) ring[size_t(n)] = r, next.push_back(n);
    std::sort(next.begin(), next.end());
    for (int h : next) {
      Eigen::Vector3f sum = Eigen::Vector3f::Zero();
      int count = 0;
      for (int n : rig_neighbors_[size_t(h)])
        if (ring[size_t(n)] >= 0 && ring[size_t(n)] < r) sum += handle_push[size_t(n)], ++count;
      if (count > 0) handle_push[size_t(h)] = options_.falloff * sum / float(count);
    }
    frontier = std::move(next);
  }
  // Each vertex its handles' pushes (apparel left inside at rest stays).
  std::vector<int> carried;
  for (int k = 0; k < Na; ++k) {
    if (!rest_inside_.empty() && rest_inside_[size_t(k)]) continue;
    Eigen::Vector3f u = Eigen::Vector3f::Zero();
    bool moves = false;
    for (Eigen::Index c = 0; c < rig_handles_.cols(); ++c) {
      const float w = rig_weights_(k, c);
      if (!(w > 0.0f) || ring[size_t(rig_handles_(k, c))] < 0) continue;
      u += w * handle_push[size_t(rig_handles_(k, c))];
      moves = true;
    }
    if (!moves) continue;
    push[size_t(k)] = u;
    carried.push_back(k);
  }
  return carried;
}

void PenetrationResolver::keep_lengths(MatrixX3f& V, const MatrixX3f& start, const std::vector<uint8_t>& moved,
                                       std::vector<uint8_t>& inside, std::vector<float>& depth) const {
  const WindingNumberTree& tree = *tree_;
  std::vector<int> list;
  for (int k = 0; k < int(moved.size()); ++k)
    if (moved[size_t(k)]) list.push_back(k);
  std::vector<Eigen::Vector3f> step(list.size());
  // Vertices at one point before the push (the copies of a split seam, which follow the same handles) take one step:
  // their edges differ (each copy has its own side's faces), and steps of their own would open the seam.
  std::vector<int> order;
  const std::vector<std::pair<int, int>> copies = coincident_runs(
      int(list.size()), [&](int t) { return start.row(list[size_t(t)]); }, order);
  for (int iteration = 0; iteration < options_.length_iterations; ++iteration) {
    // Every edge between moved apparel vertices (or from one to a vertex that stays) asks for the length it had before
    // the push; a moved vertex takes the mean of its requests (Jacobi: independent of the order).
#pragma omp parallel for schedule(dynamic, 256)
    for (int t = 0; t < int(list.size()); ++t) {
      const int k = list[size_t(t)];
      const Eigen::Vector3f p = V.row(apparel_[size_t(k)]).transpose();
      Eigen::Vector3f sum = Eigen::Vector3f::Zero();
      int count = 0;
      for (int n = apparel_adjacency_.offsets[size_t(k)]; n < apparel_adjacency_.offsets[size_t(k) + 1]; ++n) {
        const int m = apparel_adjacency_.neighbors[size_t(n)];
        const Eigen::Vector3f d = p - V.row(apparel_[size_t(m)]).transpose();
        const float length = d.norm();
        if (!(length > 1e-9f)) continue;
        const float rest = (start.row(k) - start.row(m)).norm();
        sum += (moved[size_t(m)] ? 0.5f : 1.0f) * ((rest - length) / length) * d;
        ++count;
      }
      step[size_t(t)] = count > 0 ? Eigen::Vector3f(sum / float(count)) : Eigen::Vector3f::Zero();
    }
    take_one_move(copies, order, [&](int i) -> Eigen::Vector3f& { return step[size_t(i)]; });
    for (size_t t = 0; t < list.size(); ++t) V.row(apparel_[size_t(list[t])]) += step[t].transpose();
      // Then out of the body again, one vertex at a time: a vertex outside before the step and farther from the body
      // than it moved is still outside.
#pragma omp parallel for schedule(dynamic, 64)
    for (int t = 0; t < int(list.size()); ++t) {
      const int k = list[size_t(t)];
      const Eigen::Vector3f p = V.row(apparel_[size_t(k)]).transpose();
      if (!inside[size_t(k)] && !tree.within(p, step[size_t(t)].norm())) continue;
      inside[size_t(k)] = 0;
      if (!tree.inside(p)) continue;
      Eigen::Vector3f closest;
      const float d = tree.distance(p, &closest, &exposed_);
      if (d > 1e-9f) V.row(apparel_[size_t(k)]) += ((closest - p) * ((d + options_.margin) / d)).transpose();
      // Out unless pushed into an overlapping part: known at the end.
      inside[size_t(k)] = 2;
      depth[size_t(k)] = d;
    }
  }
  // The vertices pushed in the last pass are tested once more: inside after it counts as inside after.
#pragma omp parallel for schedule(dynamic, 64)
  for (int t = 0; t < int(list.size()); ++t) {
    const int k = list[size_t(t)];
    if (inside[size_t(k)] != 2) continue;
    const Eigen::Vector3f p = V.row(apparel_[size_t(k)]).transpose();
    inside[size_t(k)] = tree.inside(p) ? 1 : 0;
    if (inside[size_t(k)]) depth[size_t(k)] = tree.distance(p, nullptr, &exposed_);
  }
}

PenetrationReport PenetrationResolver::resolve(MatrixX3f& V) {
  PenetrationReport report;
  const int Na = int(apparel_.size());
  report.before.total = report.after.total = Na;
  if (Na == 0 || body_faces_.rows() == 0) return report;
  AMT_CHECK(V.rows() == Eigen::Index(apparel_.size() + body_.size()), "penetration: expected ",
            apparel_.size() + body_.size(), " vertices, found ", V.rows());
  const WindingNumberTree& tree = posed_body(V);
  report.carried = classify(V);
  // Push: every inside vertex to its closest exposed body point plus the margin along the way out.
  std::vector<Eigen::Vector3f> push(size_t(Na), Eigen::Vector3f::Zero());
  std::vector<float> depth(size_t(Na), 0.0f);
  const std::vector<uint8_t>& inside = inside_;
  // Apparel inside the body at rest stays where the artist put it (keep_rest_penetration): not pushed, not spread to.
  const auto tucked = [&](int k) { return !rest_inside_.empty() && rest_inside_[size_t(k)]; };
#pragma omp parallel for schedule(dynamic, 64)
  for (int k = 0; k < Na; ++k) {
    if (!inside[size_t(k)]) continue;
    const Eigen::Vector3f p = V.row(apparel_[size_t(k)]).transpose();
    Eigen::Vector3f closest;
    const float d = tree.distance(p, &closest, &exposed_);
    depth[size_t(k)] = d;
    if (d > 1e-9f) {
      push[size_t(k)] = (closest - p) * ((d + options_.margin) / d);
    }
  }
  for (int k = 0; k < Na; ++k) {
    if (!inside[size_t(k)]) continue;
    ++report.before.inside;
    report.before.depth_sum_cm += 100.0 * double(depth[size_t(k)]);
    if (tucked(k)) {
      ++report.tucked;
      report.after.inside++, report.after.depth_sum_cm += 100.0 * double(depth[size_t(k)]);
    } else {
      ++report.pushed;
    }
  }
  if (report.pushed == 0) {
    report.after = report.before;
    return report;
  }
  if (rig_size_ > 0) {
    // Through the handles (set_rig), in rounds: the vertices still inside after a round push again, through their
    // handles, up to kMaxPushes rounds; what is inside after the last stays.
    std::vector<uint8_t> pushing(size_t(Na), 0), moved(size_t(Na), 0);
    for (int k = 0; k < Na; ++k) pushing[size_t(k)] = inside[size_t(k)] && !tucked(k);
    // The apparel as it came (its edge lengths are what the pieces keep through the push; below).
    MatrixX3f start(options_.length_iterations > 0 ? Na : 0, 3);
    for (int k = 0; k < start.rows(); ++k) start.row(k) = V.row(apparel_[size_t(k)]);
    std::vector<float> still(size_t(Na), -1.0f);
    tree_->update_far_field();  // when every verdict carried over, classify() did not need it
    for (int round = 1;; ++round) {
      const std::vector<int> carried = spread_through_rig(pushing, push);
      for (int k : carried) V.row(apparel_[size_t(k)]) += push[size_t(k)].transpose(), moved[size_t(k)] = 1;
        // A vertex outside before the move is still outside when the body is farther from it than it moved (see
        // below); the others are tested.
#pragma omp parallel for schedule(dynamic, 64)
      for (int t = 0; t < int(carried.size()); ++t) {
        const int k = carried[size_t(t)];
        const Eigen::Vector3f p = V.row(apparel_[size_t(k)]).transpose();
        still[size_t(k)] = -1.0f;
        if (!pushing[size_t(k)] && !tree.within(p, push[size_t(k)].norm())) continue;
        if (!tree.inside(p)) continue;
        Eigen::Vector3f closest;
        const float d = tree.distance(p, &closest, &exposed_);
        still[size_t(k)] = d;
        push[size_t(k)] =
            d > 1e-9f ? Eigen::Vector3f((closest - p) * ((d + options_.margin) / d)) : Eigen::Vector3f::Zero();
      }
      bool any = false;
      std::fill(pushing.begin(), pushing.end(), 0);
      for (int k : carried) any |= (pushing[size_t(k)] = still[size_t(k)] >= 0.0f) != 0;
      if (!any || round == kMaxPushes) break;
    }
    if (options_.length_iterations > 0) keep_lengths(V, start, moved, pushing, still);
    for (int k = 0; k < Na; ++k) {
      if (pushing[size_t(k)]) ++report.after.inside, report.after.depth_sum_cm += 100.0 * double(still[size_t(k)]);
      if (moved[size_t(k)] && !inside[size_t(k)]) ++report.smoothed;
    }
    return report;
  }
  // Tucked vertices take no spread either (ring -2: never a ring of the spread, never moved).
  std::vector<int> ring(size_t(Na), -1);
  std::vector<int> frontier;
  for (int k = 0; k < Na; ++k) {
    if (tucked(k)) {
      ring[size_t(k)] = -2;
    } else if (inside[size_t(k)]) {
      ring[size_t(k)] = 0;
      frontier.push_back(k);
    }
  }
  // Spread: ring r around the pushed vertices takes falloff^r of the mean push of its pushed-or-spread
  // neighbours of the previous rings (pushed vertices keep their full push).
  for (int r = 1; r <= options_.smoothing_rings && !frontier.empty(); ++r) {
    std::vector<int> next;
    for (int k : frontier) {
      for (int n = apparel_adjacency_.offsets[size_t(k)]; n < apparel_adjacency_.offsets[size_t(k) + 1]; ++n) {
        const int m = apparel_adjacency_.neighbors[size_t(n)];
        if (ring[size_t(m)] == -1) ring[size_t(m)] = r, next.push_back(m);
      }
    }
    std::sort(next.begin(), next.end());
    for (int m : next) {
      Eigen::Vector3f sum = Eigen::Vector3f::Zero();
      int count = 0;
      for (int n = apparel_adjacency_.offsets[size_t(m)]; n < apparel_adjacency_.offsets[size_t(m) + 1]; ++n) {
        const int q = apparel_adjacency_.neighbors[size_t(n)];
        if (ring[size_t(q)] >= 0 && ring[size_t(q)] < r) sum += push[size_t(q)], ++count;
      }
      if (count > 0) push[size_t(m)] = options_.falloff * sum / float(count);
    }
    report.smoothed += int(next.size());
    frontier = std::move(next);
  }
  // The copies of a split seam (at one point) take one push: each copy's ring neighbours lie on its own side.
  {
    std::vector<int> spread, order;
    for (int k = 0; k < Na; ++k)
      if (ring[size_t(k)] >= 0) spread.push_back(k);
    const std::vector<std::pair<int, int>> copies = coincident_runs(
        int(spread.size()), [&](int t) { return V.row(apparel_[size_t(spread[size_t(t)])]).transpose(); }, order);
    take_one_move(copies, order, [&](int t) -> Eigen::Vector3f& { return push[size_t(spread[size_t(t)])]; });
  }
  // Apply, then re-test the moved vertices (the others keep their verdict: outside); one still inside
  // (pushed out of one part into an overlapping one) is pushed again, up to kMaxPushes pushes in all.
  std::vector<int> moved;
  for (int k = 0; k < Na; ++k) {
    if (ring[size_t(k)] >= 0) {
      V.row(apparel_[size_t(k)]) += push[size_t(k)].transpose();
      moved.push_back(k);
    }
  }
  // A smoothed vertex was outside and the body has not moved since: it is still outside when the body is
  // farther from it than it moved (its straight path cannot have met the surface), without a winding
  // number, which costs most near the large fans that close a body with big holes.
  std::vector<float> still(moved.size(), -1.0f);
  std::vector<Eigen::Vector3f> again(moved.size());
  std::vector<int> test(moved.size());
  for (size_t m = 0; m < moved.size(); ++m) test[m] = int(m);
  tree_->update_far_field();  // when every verdict carried over, classify() did not need it
  for (int pushes = 1;; ++pushes) {
#pragma omp parallel for schedule(dynamic, 64)
    for (int t = 0; t < int(test.size()); ++t) {
      const int m = test[size_t(t)], k = moved[size_t(m)];
      const Eigen::Vector3f p = V.row(apparel_[size_t(k)]).transpose();
      still[size_t(m)] = -1.0f;
      again[size_t(m)].setZero();
      if (pushes == 1 && ring[size_t(k)] > 0 && !tree.within(p, push[size_t(k)].norm())) continue;
      if (!tree.inside(p)) continue;
      Eigen::Vector3f closest;
      const float d = tree.distance(p, &closest, &exposed_);
      still[size_t(m)] = d;
      if (d > 1e-9f) again[size_t(m)] = (closest - p) * ((d + options_.margin) / d);
    }
    if (pushes == kMaxPushes) break;
    std::vector<int> pushed;
    for (const int m : test) {
      if (still[size_t(m)] < 0) continue;
      V.row(apparel_[size_t(moved[size_t(m)])]) += again[size_t(m)].transpose();
      pushed.push_back(m);
    }
    if (pushed.empty()) break;
    test = std::move(pushed);
  }
  for (float d : still) {
    if (d >= 0) ++report.after.inside, report.after.depth_sum_cm += 100.0 * double(d);
  }
  return report;
}

}  // namespace amt
