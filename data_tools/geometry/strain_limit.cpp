#include "data_tools/geometry/strain_limit.h"

#include <cmath>
#include <utility>

#include "data_tools/geometry/error.h"

namespace amt {

StrainLimiter::StrainLimiter(const MatrixX2i& edges, const std::vector<float>& rest, int num_free, int num_fixed,
                             float max_stretch, int iterations, float weld_length, float min_stretch)
    : num_free_(num_free),
      num_fixed_(num_fixed),
      iterations_(iterations),
      max_stretch_(max_stretch),
      min_stretch_(min_stretch) {
  AMT_CHECK(size_t(edges.rows()) == rest.size(), "strain limit: expected a rest length per edge (", edges.rows(),
            "), found ", rest.size());
  AMT_CHECK(num_free >= 0 && num_fixed >= 0, "strain limit: expected vertex counts >= 0, found ", num_free, " and ",
            num_fixed);
  AMT_CHECK(std::isfinite(max_stretch) && max_stretch > 1.0f && max_stretch <= 100.0f,
            "strain limit: expected a largest stretch in (1, 100], found ", max_stretch);
  AMT_CHECK(std::isfinite(min_stretch) && min_stretch >= 0.0f && min_stretch < 1.0f,
            "strain limit: expected a smallest stretch in [0, 1), found ", min_stretch);
  AMT_CHECK(iterations >= 1 && iterations <= 1000, "strain limit: expected 1 to 1000 iterations, found ", iterations);
  const int n = num_free + num_fixed;
  // Welded vertices: union-find over free and fixed ones. A group's representative is its smallest fixed vertex
  // when it has one (the free copies of a body vertex are pinned to it: a floor pushing them off the body would
  // otherwise fight the weld pulling them back and leave the seam open), else its smallest free vertex.
  std::vector<int32_t> rep(static_cast<size_t>(n));
  for (int v = 0; v < n; ++v) rep[size_t(v)] = v;
  const auto find = [&](int v) {
    while (rep[size_t(v)] != v) v = rep[size_t(v)] = rep[size_t(rep[size_t(v)])];
    return v;
  };
  for (Eigen::Index e = 0; e < edges.rows(); ++e) {
    const int a = edges(e, 0), b = edges(e, 1);
    AMT_CHECK(a >= 0 && a < n && b >= 0 && b < n && a != b, "strain limit: edge ", e, ": expected two vertices in [0, ",
              n, "), found (", a, ", ", b, ")");
    AMT_CHECK(std::isfinite(rest[size_t(e)]) && rest[size_t(e)] >= 0.0f, "strain limit: edge ", e,
              ": expected a rest length >= 0, found ", rest[size_t(e)]);
    if ((a < num_free || b < num_free) && rest[size_t(e)] < weld_length) {
      const int ra = find(a), rb = find(b);
      // Fixed vertices rank before free ones, each in index order.
      const auto rank = [&](int r) { return r >= num_free ? r - num_free : n + r; };
      if (ra != rb) {
        if (rank(ra) < rank(rb))
          rep[size_t(rb)] = ra;
        else
          rep[size_t(ra)] = rb;
      }
    }
  }
  for (int v = 0; v < num_free; ++v) {
    if (find(v) != v) copies_.insert(copies_.end(), {v, find(v)});
  }
  for (Eigen::Index e = 0; e < edges.rows(); ++e) {
    // Free ends stand for their groups (which may be a fixed vertex); a fixed end stays itself.
    int a = edges(e, 0), b = edges(e, 1);
    if (a < num_free) a = find(a);
    if (b < num_free) b = find(b);
    if (a >= num_free) std::swap(a, b);
    if (a >= num_free || a == b) continue;  // both ends fixed or pinned, or within one welded point: nothing to move
    a_.push_back(a);
    b_.push_back(b);
    rest_.push_back(rest[size_t(e)]);
    const float high = (1.0f + kStrainSlack) * max_stretch * rest[size_t(e)];
    const float low = (1.0f - kStrainSlack) * min_stretch * rest[size_t(e)];
    bound2_.push_back(high * high);
    floor2_.push_back(low * low);
  }
  // Each free vertex's edges (compressed rows), for the iterations after the first.
  incident_offsets_.assign(size_t(num_free) + 1, 0);
  for (size_t e = 0; e < a_.size(); ++e) {
    ++incident_offsets_[size_t(a_[e]) + 1];
    if (b_[e] < num_free) ++incident_offsets_[size_t(b_[e]) + 1];
  }
  for (size_t v = 0; v < size_t(num_free); ++v) incident_offsets_[v + 1] += incident_offsets_[v];
  incident_.resize(size_t(incident_offsets_.back()));
  std::vector<int32_t> fill(incident_offsets_.begin(), incident_offsets_.end() - 1);
  for (size_t e = 0; e < a_.size(); ++e) {
    incident_[size_t(fill[size_t(a_[e])]++)] = int32_t(e);
    if (b_[e] < num_free) incident_[size_t(fill[size_t(b_[e])]++)] = int32_t(e);
  }
}

void StrainLimiter::apply(float* free_xyz, const float* fixed_xyz) const {
  if (empty()) return;
  // The first iteration tests every edge (a squared-length test first, no square root); later ones only the edges
  // of the vertices the previous one moved (an edge whose ends stayed put is still within its bounds), in edge
  // order, so the result is that of testing every edge every time. Only the vertices hit are updated and cleared.
  std::vector<float> delta(size_t(num_free_) * 3, 0.0f);
  std::vector<int> hits(static_cast<size_t>(num_free_), 0);
  std::vector<int32_t> touched, active;
  std::vector<uint64_t> marked((a_.size() + 63) / 64, 0);
  const auto at = [&](int v) -> const float* {
    return v < num_free_ ? free_xyz + size_t(v) * 3 : fixed_xyz + size_t(v - num_free_) * 3;
  };
  for (int it = 0; it < iterations_; ++it) {
    const bool all = it == 0;
    const size_t count = all ? a_.size() : active.size();
    touched.clear();
    for (size_t i = 0; i < count; ++i) {
      const size_t e = all ? i : size_t(active[i]);
      const float* pa = at(a_[e]);
      const float* pb = at(b_[e]);
      const float d[3] = {pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]};
      const float squared = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
      const bool stretched = squared > bound2_[e];
      // Within the bounds, or collapsed to a point (no direction to open it along); a NaN is left to the caller.
      if (!(stretched || squared < floor2_[e]) || !(squared > 0.0f)) continue;
      const float length = std::sqrt(squared);
      const float bound = (stretched ? max_stretch_ : min_stretch_) * rest_[e];
      const bool both = b_[e] < num_free_;
      // Share of d each free end moves: towards the other end when stretched, away from it when squashed.
      const float s = (length - bound) / length * (both ? 0.5f : 1.0f);
      for (int k = 0; k < 3; ++k) {
        delta[size_t(a_[e]) * 3 + k] += s * d[k];
        if (both) delta[size_t(b_[e]) * 3 + k] -= s * d[k];
      }
      if (hits[size_t(a_[e])]++ == 0) touched.push_back(a_[e]);
      if (both && hits[size_t(b_[e])]++ == 0) touched.push_back(b_[e]);
    }
    if (touched.empty()) break;
    // The moved vertices' edges, each once and in edge order: marked in a bit set, read back word by word (sorting
    // the list instead cost most of the limit's time: about 1 ms a frame on a 28k-vertex remake).
    for (const int32_t v : touched) {
      for (int32_t k = incident_offsets_[size_t(v)]; k < incident_offsets_[size_t(v) + 1]; ++k) {
        const uint32_t e = uint32_t(incident_[size_t(k)]);
        marked[e >> 6] |= uint64_t(1) << (e & 63);
      }
    }
    active.clear();
    for (size_t w = 0; w < marked.size(); ++w) {
      for (uint64_t bits = marked[w]; bits != 0; bits &= bits - 1)
        active.push_back(int32_t(w * 64 + size_t(__builtin_ctzll(bits))));
      marked[w] = 0;
    }
    for (const int32_t v : touched) {
      const float w = 1.0f / float(hits[size_t(v)]);
      for (int k = 0; k < 3; ++k) {
        free_xyz[size_t(v) * 3 + k] += w * delta[size_t(v) * 3 + k];
        delta[size_t(v) * 3 + k] = 0.0f;
      }
      hits[size_t(v)] = 0;
    }
  }
  for (size_t k = 0; k < copies_.size(); k += 2) {
    const float* from = at(copies_[k + 1]);  // read before the write: a copy is never its own representative
    for (int c = 0; c < 3; ++c) free_xyz[size_t(copies_[k]) * 3 + c] = from[c];
  }
}

}  // namespace amt
