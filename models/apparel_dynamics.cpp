#include "models/apparel_dynamics.h"

#include <ATen/ATen.h>
#include <torch/utils.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <queue>
#include <string>

#include "data_tools/geometry/apparel_topology.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/geodesic.h"
#include "models/apparel_displacement.h"
#include "models/module_options.h"
#include "models/pointnet.h"

namespace amt {

static_assert(kApparelResponseChannels == kRigResponseChannels, "one response layout for rigs and the module");
namespace {

// R^T v and R v for rotations R (..., 3, 3) and vectors v (..., 3), elementwise (a batched matmul
// of 3x3 matrices costs more than the nine products).
at::Tensor to_frame(const at::Tensor& R, const at::Tensor& v) { return (R * v.unsqueeze(-1)).sum(-2); }
at::Tensor from_frame(const at::Tensor& R, const at::Tensor& v) { return (R * v.unsqueeze(-2)).sum(-1); }

// The axial vector of the skew part of M (..., 3, 3): sin(angle) times the axis for a rotation.
at::Tensor axial(const at::Tensor& M) {
  const auto m = [&](int64_t a, int64_t b) { return M.select(-2, a).select(-1, b); };
  return 0.5 * at::stack({m(2, 1) - m(1, 2), m(0, 2) - m(2, 0), m(1, 0) - m(0, 1)}, -1);
}

// Per-vertex rotations (B, F, N_a, 3, 3) of the frame joints from transforms (B, F, J, 3, 4).
at::Tensor vertex_rotations(const at::Tensor& transforms, const at::Tensor& frame_joints) {
  return transforms.narrow(-1, 0, 3).index_select(2, frame_joints);
}

// The contact points P (B, N_a, 3) of one frame: the rest points p (N_a, 3) skinned with weights W
// (N_a, J) by that frame's transforms T (B, J, 3, 4), sum_j W_ij (R_j p_i + t_j).
at::Tensor contact_points(const at::Tensor& p, const at::Tensor& W, const at::Tensor& T) {
  const int64_t B = T.size(0), J = T.size(1), N = p.size(0);
  const at::Tensor M = at::matmul(W, T.reshape({B, J, 12})).view({B, N, 3, 4});  // blended [R | t] per point
  return (M.narrow(-1, 0, 3) * p.view({1, N, 1, 3})).sum(-1) + M.select(-1, 3);
}

// Detail vectors of the three history frames: d[k] (B, N_a, 3) for frames t-3+k.
std::vector<at::Tensor> history_details(const at::Tensor& history, const at::Tensor& anchors, const at::Tensor& R) {
  std::vector<at::Tensor> d;
  for (int64_t k = 0; k < 3; ++k) d.push_back(to_frame(R.select(1, k), history.select(1, k) - anchors.select(1, k)));
  return d;
}

void check_inputs(const at::Tensor& h, const at::Tensor& T, const at::Tensor& S, const ApparelGraph& g, int64_t J,
                  bool contact, int64_t reach, const char* who) {
  TORCH_CHECK(h.dim() == 4 && h.size(1) == 3 && h.size(3) == 3, who, ": history must be (3, N_a, 3) or (B, 3, N_a, 3), got ",
              h.sizes());
  const int64_t B = h.size(0), N = h.size(2);
  TORCH_CHECK(T.dim() == 5 && T.size(0) == B && T.size(1) == 4 && T.size(2) == J && T.size(3) == 3 && T.size(4) == 4,
              who, ": transforms must be (4, ", J, ", 3, 4) or (", B, ", 4, ", J, ", 3, 4), got ", T.sizes());
  TORCH_CHECK(S.dim() == 4 && S.size(0) == B && S.size(1) == 4 && S.size(2) == N && S.size(3) == 3, who,
              ": anchors must be (4, ", N, ", 3) or (", B, ", 4, ", N, ", 3), got ", S.sizes());
  TORCH_CHECK(g.frame_joints.defined() && g.frame_joints.dim() == 1 && g.frame_joints.size(0) == N, who,
              ": graph.frame_joints must be (", N, ")");
  TORCH_CHECK(g.rest_features.defined() && g.rest_features.dim() == 2 && g.rest_features.size(0) == N &&
                  g.rest_features.size(1) == kApparelRestChannels,
              who, ": graph.rest_features must be (", N, ", ", kApparelRestChannels, ")");
  TORCH_CHECK(g.neighbors.defined() && g.neighbors.dim() == 2 && g.neighbors.size(0) == N, who,
              ": graph.neighbors must be (", N, ", K_max)");
  TORCH_CHECK(reach == 0 || (g.ancestors.defined() && g.ancestors.dim() == 2 && g.ancestors.size(0) == N &&
                              g.ancestors.size(1) >= reach),
              who, ": ", reach, " reach levels need graph.ancestors (", N, ", >= ", reach, ") (apparel_graph)");
  if (contact) {
    TORCH_CHECK(g.contact_rest.defined() && g.contact_rest.dim() == 2 && g.contact_rest.size(0) == N &&
                    g.contact_rest.size(1) == 3 && g.contact_weights.defined() && g.contact_weights.dim() == 2 &&
                    g.contact_weights.size(0) == N && g.contact_weights.size(1) == J,
                who, ": the contact inputs need graph.contact_rest (", N, ", 3) and graph.contact_weights (", N, ", ", J,
                ") (apparel_graph with the body weights)");
  }
  TORCH_CHECK(!g.response.defined() ||
                  (g.response.dim() == 2 && g.response.size(0) == N && g.response.size(1) == kApparelResponseChannels),
              who, ": graph.response must be (", N, ", ", kApparelResponseChannels, ") or undefined");
}

// The inference path of features_from in one pass (no autograd): the same channels, computed per vertex
// from the raw arrays instead of through some forty tensor operations on (B, 4, N_a, 3, 3) rotations,
// which cost more than the network's products at run time (a profile of the runtime step). The blended
// contact transforms of both frames stay one matrix product. Values agree with features_from to float
// rounding (tested). Inputs float32 and contiguous.
// Returns the channels normalised by (mean, scale) (the input normaliser's), and the raw first six
// (d_{t-1}, d_{t-1} - d_{t-2}) in `raw` (B, N_a, 6).
at::Tensor fused_features(const at::Tensor& h, const at::Tensor& T, const at::Tensor& S, const ApparelGraph& g,
                          bool contact, bool response, int64_t channels, const at::Tensor& mean,
                          const at::Tensor& scale, at::Tensor& raw) {
  constexpr int64_t kMaxChannels = 64;
  TORCH_CHECK(channels <= kMaxChannels, "fused_features: at most ", kMaxChannels, " channels");
  const int64_t B = h.size(0), N = h.size(2), J = T.size(2);
  at::Tensor X = at::empty({B, N, channels}, at::kFloat);
  raw = at::empty({B, N, 6}, at::kFloat);
  const at::Tensor m = mean.to(at::kFloat).contiguous(), sc = scale.to(at::kFloat).contiguous();
  const float* mp = m.data_ptr<float>();
  const float* sp = sc.data_ptr<float>();
  float* rp = raw.data_ptr<float>();
  // The blended contact transforms [R | t] (B, 2, N_a, 12) of frames t-1 and t: one product for both.
  at::Tensor M;
  const float* cr = nullptr;
  if (contact) {
    M = at::matmul(g.contact_weights, T.narrow(1, 2, 2).reshape({B, 2, J, 12})).contiguous();
    cr = g.contact_rest.data_ptr<float>();
  }
  const float* hp = h.data_ptr<float>();
  const float* Tp = T.data_ptr<float>();
  const float* Sp = S.data_ptr<float>();
  const float* rest = g.rest_features.data_ptr<float>();
  const int64_t* fj = g.frame_joints.data_ptr<int64_t>();
  const float* mp_contact = contact ? M.data_ptr<float>() : nullptr;
  const float* physics = response && g.response.defined() ? g.response.data_ptr<float>() : nullptr;
  const int64_t physics_at = channels - kApparelResponseChannels;
  float* out = X.data_ptr<float>();
  // Per joint: the axial vectors of R_2^T R_3 and R_1^T R_2, and gravity in the frame at t, (B, J, 9).
  std::vector<float> joint(static_cast<size_t>(B * J * 9));
  const auto rot = [&](int64_t b, int64_t k, int64_t j) { return Tp + (((b * 4 + k) * J + j) * 12); };  // row-major 3x4
  for (int64_t b = 0; b < B; ++b) {
    for (int64_t j = 0; j < J; ++j) {
      float* o = joint.data() + (b * J + j) * 9;
      for (int pair = 0; pair < 2; ++pair) {
        const float* A = rot(b, pair == 0 ? 2 : 1, j);  // R_a
        const float* C = rot(b, pair == 0 ? 3 : 2, j);  // R_b
        const auto m = [&](int r, int c) {              // (R_a^T R_b)_rc = sum_k A_kr C_kc
          return A[0 * 4 + r] * C[0 * 4 + c] + A[1 * 4 + r] * C[1 * 4 + c] + A[2 * 4 + r] * C[2 * 4 + c];
        };
        o[pair * 3 + 0] = 0.5f * (m(2, 1) - m(1, 2));
        o[pair * 3 + 1] = 0.5f * (m(0, 2) - m(2, 0));
        o[pair * 3 + 2] = 0.5f * (m(1, 0) - m(0, 1));
      }
      const float* R3 = rot(b, 3, j);
      for (int c = 0; c < 3; ++c) o[6 + c] = -R3[1 * 4 + c];
    }
  }
  at::parallel_for(0, B * N, 256, [&](int64_t begin, int64_t end) {
    for (int64_t bi = begin; bi < end; ++bi) {
      const int64_t b = bi / N, i = bi % N, j = fj[i];
      float o[kMaxChannels];
      const auto vec = [&](const float* base, int64_t frames, int64_t k) {
        return base + ((b * frames + k) * N + i) * 3;
      };
      // R^T v for the rotation of joint j at frame k.
      const auto to = [&](int64_t k, const float v[3], float* dst) {
        const float* R = rot(b, k, j);
        for (int c = 0; c < 3; ++c) dst[c] = R[0 * 4 + c] * v[0] + R[1 * 4 + c] * v[1] + R[2 * 4 + c] * v[2];
      };
      float d[3][3];
      for (int64_t k = 0; k < 3; ++k) {
        const float* a = vec(hp, 3, k);
        const float* s = vec(Sp, 4, k);
        const float v[3] = {a[0] - s[0], a[1] - s[1], a[2] - s[2]};
        to(k, v, d[k]);
      }
      for (int c = 0; c < 3; ++c) o[c] = d[2][c], o[3 + c] = d[2][c] - d[1][c], o[6 + c] = d[1][c] - d[0][c];
      for (int64_t k = 0; k < 3; ++k) {  // channels 9-17: S_{t-k} - S_{t-k-1} for k = 0, 1, 2
        const float* s1 = vec(Sp, 4, 3 - k);
        const float* s0 = vec(Sp, 4, 2 - k);
        const float v[3] = {s1[0] - s0[0], s1[1] - s0[1], s1[2] - s0[2]};
        to(2, v, o + 9 + 3 * k);
      }
      const float* a2 = vec(hp, 3, 2);
      const float* a1 = vec(hp, 3, 1);
      const float move[3] = {a2[0] - a1[0], a2[1] - a1[1], a2[2] - a1[2]};
      to(2, move, o + 18);
      const float* jv = joint.data() + (b * J + j) * 9;
      for (int c = 0; c < 9; ++c) o[21 + c] = jv[c];
      for (int c = 0; c < kApparelRestChannels; ++c) o[30 + c] = rest[i * kApparelRestChannels + c];
      if (contact) {
        // The contact point of frames t-1 and t: the blended [R | t] applied to the rest point (contact_points).
        float l[3], n[3];
        const float* p = cr + i * 3;
        for (int64_t f = 0; f < 2; ++f) {
          const float* m = mp_contact + ((b * 2 + f) * N + i) * 12;
          float* P = f == 0 ? l : n;
          for (int r = 0; r < 3; ++r)
            P[r] = (m[r * 4 + 0] * p[0] + m[r * 4 + 1] * p[1] + m[r * 4 + 2] * p[2]) + m[r * 4 + 3];
        }
        const float reach[3] = {n[0] - a2[0], n[1] - a2[1], n[2] - a2[2]};
        const float step[3] = {n[0] - l[0], n[1] - l[1], n[2] - l[2]};
        to(2, reach, o + 37);
        to(2, step, o + 40);
      }
      if (response) {
        for (int64_t c = 0; c < kApparelResponseChannels; ++c)
          o[physics_at + c] = physics ? physics[i * kApparelResponseChannels + c] : 0.0f;
      }
      float* x = out + bi * channels;
      for (int64_t c = 0; c < channels; ++c) x[c] = (o[c] - mp[c]) / sp[c];  // RunningNormalizer::normalize
      std::copy(o, o + 6, rp + bi * 6);
    }
  });
  return X;
}

// Whether the fused loops can read the inputs as they are: float32, contiguous, on the CPU.
bool fused_inputs(const at::Tensor& h, const at::Tensor& T, const at::Tensor& S, const ApparelGraph& g) {
  const auto plain = [](const at::Tensor& t, at::ScalarType type) {
    return !t.defined() || (t.scalar_type() == type && t.is_contiguous() && t.device().is_cpu());
  };
  return plain(h, at::kFloat) && plain(T, at::kFloat) && plain(S, at::kFloat) && plain(g.rest_features, at::kFloat) &&
         plain(g.frame_joints, at::kLong) && plain(g.contact_rest, at::kFloat) &&
         plain(g.contact_weights, at::kFloat) && plain(g.response, at::kFloat);
}

// S_t + R_t d_t per vertex (the inference path of step's last line): S (B, 4, N_a, 3), d (B, N_a, 3).
at::Tensor fused_output(const at::Tensor& T, const at::Tensor& S, const at::Tensor& d, const at::Tensor& frame_joints) {
  const int64_t B = d.size(0), N = d.size(1), J = T.size(2);
  at::Tensor A = at::empty({B, N, 3}, at::kFloat);
  const float* Tp = T.data_ptr<float>();
  const float* Sp = S.data_ptr<float>();
  const float* dp = d.data_ptr<float>();
  const int64_t* fj = frame_joints.data_ptr<int64_t>();
  float* out = A.data_ptr<float>();
  at::parallel_for(0, B * N, 1024, [&](int64_t begin, int64_t end) {
    for (int64_t bi = begin; bi < end; ++bi) {
      const int64_t b = bi / N, i = bi % N;
      const float* R = Tp + ((b * 4 + 3) * J + fj[i]) * 12;
      const float* s = Sp + ((b * 4 + 3) * N + i) * 3;
      const float* v = dp + bi * 3;
      // Summed in from_frame's order, so that a zero network reproduces the rule exactly.
      for (int r = 0; r < 3; ++r)
        out[bi * 3 + r] = s[r] + ((R[r * 4 + 0] * v[0] + R[r * 4 + 1] * v[1]) + R[r * 4 + 2] * v[2]);
    }
  });
  return A;
}

}  // namespace

// === Per-character inputs

namespace {

// Geodesic distance along the apparel from where each piece attaches to the body, and the body vertex
// it attaches at (the seed's body neighbour, or the nearest body vertex of a detached piece's seed).
struct Attachment {
  std::vector<float> distance;
  std::vector<int64_t> body_vertex;
  /// The next apparel vertex (position in apparel_ids) on the shortest path towards the attachment,
  /// or the vertex itself where the path leaves the apparel (a seed) or there is none.
  std::vector<int64_t> toward_body;
};

Attachment attachments(const at::Tensor& V, const at::Tensor& edges, const at::Tensor& apparel_ids,
                       const at::Tensor& body_ids) {
  const int64_t N = V.size(0), N_a = apparel_ids.size(0);
  Attachment out;
  out.distance.assign(static_cast<size_t>(N_a), 0.0f);
  out.body_vertex.assign(static_cast<size_t>(N_a), -1);
  out.toward_body.resize(static_cast<size_t>(N_a));
  for (int64_t i = 0; i < N_a; ++i) out.toward_body[i] = i;
  if (N_a == 0 || body_ids.size(0) == 0) return out;
  const at::Tensor Vc = V.to(at::kFloat).contiguous(), E = edges.to(at::kLong).contiguous();
  const float* v = Vc.data_ptr<float>();
  const int64_t* e = E.data_ptr<int64_t>();
  const at::Tensor ids = apparel_ids.to(at::kLong).contiguous(), bids = body_ids.to(at::kLong).contiguous();
  std::vector<int64_t> position(static_cast<size_t>(N), -1);  // apparel position, or -1 for body
  for (int64_t i = 0; i < N_a; ++i) position[ids.data_ptr<int64_t>()[i]] = i;
  const auto length = [&](int64_t a, int64_t b) {
    const float dx = v[3 * a] - v[3 * b], dy = v[3 * a + 1] - v[3 * b + 1], dz = v[3 * a + 2] - v[3 * b + 2];
    return std::sqrt(dx * dx + dy * dy + dz * dz);
  };
  // Apparel adjacency, components, and seeds where a piece's mesh touches the body.
  std::vector<std::vector<std::pair<int64_t, float>>> adjacency(static_cast<size_t>(N_a));
  std::vector<float> dist(static_cast<size_t>(N_a), std::numeric_limits<float>::infinity());
  std::vector<int64_t> source(static_cast<size_t>(N_a), -1);  // the body vertex each distance starts at
  std::vector<int64_t> parent(static_cast<size_t>(N_a));
  for (int64_t i = 0; i < N_a; ++i) parent[i] = i;
  const std::function<int64_t(int64_t)> root = [&](int64_t i) { return parent[i] == i ? i : parent[i] = root(parent[i]); };
  for (int64_t k = 0; k < E.size(0); ++k) {
    const int64_t a = e[2 * k], b = e[2 * k + 1], pa = position[a], pb = position[b];
    if (pa >= 0 && pb >= 0) {
      const float l = length(a, b);
      adjacency[pa].emplace_back(pb, l);
      adjacency[pb].emplace_back(pa, l);
      parent[root(pa)] = root(pb);
    } else if (pa >= 0 || pb >= 0) {
      const int64_t p = pa >= 0 ? pa : pb;
      const float l = length(a, b);
      if (l < dist[p] || (l == dist[p] && (pa >= 0 ? b : a) < source[p])) {
        dist[p] = l;
        source[p] = pa >= 0 ? b : a;
      }
    }
  }
  // A component that touches no body vertex hangs from its vertex nearest to the body.
  const std::vector<int32_t> nearest = nearest_listed_vertices(
      Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>>(v, N, 3),
      std::vector<int32_t>(bids.data_ptr<int64_t>(), bids.data_ptr<int64_t>() + bids.numel()),
      std::vector<int32_t>(ids.data_ptr<int64_t>(), ids.data_ptr<int64_t>() + N_a));
  std::vector<uint8_t> touches(static_cast<size_t>(N_a), 0);
  std::vector<int64_t> closest(static_cast<size_t>(N_a), -1);
  for (int64_t i = 0; i < N_a; ++i) {
    const int64_t r = root(i);
    if (std::isfinite(dist[i])) touches[r] = 1;
    const float gap = length(ids.data_ptr<int64_t>()[i], nearest[i]);
    if (closest[r] < 0 || gap < length(ids.data_ptr<int64_t>()[closest[r]], nearest[closest[r]])) closest[r] = i;
  }
  for (int64_t i = 0; i < N_a; ++i) {
    const int64_t r = root(i);
    if (!touches[r] && closest[r] == i) {
      dist[i] = length(ids.data_ptr<int64_t>()[i], nearest[i]);
      source[i] = nearest[i];
    }
  }
  // Dijkstra from the seeds over apparel edges.
  using Item = std::pair<float, int64_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> queue;
  for (int64_t i = 0; i < N_a; ++i)
    if (std::isfinite(dist[i])) queue.emplace(dist[i], i);
  while (!queue.empty()) {
    const auto [d, i] = queue.top();
    queue.pop();
    if (d > dist[i]) continue;
    for (const auto& [j, l] : adjacency[i]) {
      if (d + l < dist[j]) {
        queue.emplace(dist[j] = d + l, j);
        source[j] = source[i];
        out.toward_body[j] = i;
      }
    }
  }
  for (int64_t i = 0; i < N_a; ++i) {
    out.distance[i] = std::isfinite(dist[i]) ? dist[i] : 0.0f;
    out.body_vertex[i] = source[i];
  }
  return out;
}

}  // namespace

namespace {

// Jump pointers up the attachment paths (chain_ancestors) from one Attachment.
at::Tensor ancestors_of(const Attachment& a, int64_t levels) {
  const int64_t N_a = static_cast<int64_t>(a.toward_body.size());
  std::vector<int64_t> out(static_cast<size_t>(N_a * levels));
  std::vector<int64_t> up = a.toward_body, next(up.size());  // 2^0 hops
  for (int64_t l = 0; l < levels; ++l) {
    for (int64_t i = 0; i < N_a; ++i) out[i * levels + l] = up[i];
    for (int64_t i = 0; i < N_a; ++i) next[i] = up[up[i]];  // 2^(l+1) hops (a seed points at itself)
    up.swap(next);
  }
  return at::tensor(out, at::kLong).view({N_a, levels});
}

// The rows of body-part tensors (positions in the ascending body_ids) of the body vertices `vertices`
// (mesh indices).
at::Tensor body_rows(const at::Tensor& body_ids, const std::vector<int64_t>& vertices) {
  const at::Tensor b = body_ids.to(at::kLong).contiguous();
  const int64_t* first = b.data_ptr<int64_t>();
  std::vector<int64_t> rows(vertices.size());
  for (size_t i = 0; i < vertices.size(); ++i) rows[i] = std::lower_bound(first, first + b.numel(), vertices[i]) - first;
  return at::tensor(rows, at::kLong);
}

}  // namespace

at::Tensor chain_ancestors(const at::Tensor& V, const at::Tensor& edges, const at::Tensor& apparel_ids,
                           const at::Tensor& body_ids, int64_t levels) {
  TORCH_CHECK(levels >= 0, "chain_ancestors: levels must be >= 0, got ", levels);
  return ancestors_of(attachments(V, edges, apparel_ids, body_ids), levels);
}

at::Tensor attachment_distances(const at::Tensor& V, const at::Tensor& edges, const at::Tensor& apparel_ids,
                                const at::Tensor& body_ids) {
  const Attachment a = attachments(V, edges, apparel_ids, body_ids);
  return at::tensor(a.distance, at::kFloat);
}

at::Tensor attachment_anchor_weights(const at::Tensor& V, const at::Tensor& edges, const at::Tensor& apparel_ids,
                                     const at::Tensor& body_ids, const at::Tensor& body_weights) {
  TORCH_CHECK(body_weights.dim() == 2 && body_weights.size(0) == body_ids.size(0),
              "attachment_anchor_weights: body_weights must be (", body_ids.size(0), ", J), got ", body_weights.sizes());
  const int64_t N_a = apparel_ids.size(0);
  // Without body vertices there is nothing to attach to: the nearest rule's fallback (the first joint).
  if (body_ids.size(0) == 0) return apparel_anchor_weights(V, apparel_ids, body_ids, body_weights);
  const Attachment a = attachments(V, edges, apparel_ids, body_ids);
  TORCH_CHECK(static_cast<int64_t>(a.body_vertex.size()) == N_a, "attachment_anchor_weights: one attachment per vertex");
  return body_weights.index_select(0, body_rows(body_ids, a.body_vertex));
}

ApparelGraph apparel_graph(const at::Tensor& V, const at::Tensor& edges, const at::Tensor& apparel_ids,
                           const at::Tensor& body_ids, const at::Tensor& anchor_weights, const at::Tensor& rest_joints,
                           const at::Tensor& apparel_neighbors, const at::Tensor& body_weights) {
  torch::NoGradGuard no_grad;
  ApparelGraph g;
  g.neighbors = apparel_neighbors;
  const int64_t N_a = apparel_ids.size(0);
  g.frame_joints = N_a > 0 ? anchor_weights.argmax(1).to(at::kLong).contiguous() : at::zeros({0}, at::kLong);
  const at::Tensor A_rest = V.to(at::kFloat).index_select(0, apparel_ids.to(at::kLong));
  const at::Tensor to_joint = A_rest - rest_joints.to(at::kFloat).index_select(0, g.frame_joints);
  at::Tensor to_body = at::zeros({N_a, 3}, at::kFloat);
  if (body_weights.defined()) {
    // Without body vertices the contact point is the vertex itself, carried by its anchor.
    g.contact_rest = A_rest.contiguous();
    g.contact_weights = anchor_weights.to(at::kFloat).contiguous();
  }
  if (N_a > 0 && body_ids.size(0) > 0) {
    const at::Tensor Vc = V.to(at::kFloat).contiguous();
    const at::Tensor ids = apparel_ids.to(at::kLong).contiguous(), bids = body_ids.to(at::kLong).contiguous();
    const std::vector<int32_t> nearest = nearest_listed_vertices(
        Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>>(Vc.data_ptr<float>(), Vc.size(0), 3),
        std::vector<int32_t>(bids.data_ptr<int64_t>(), bids.data_ptr<int64_t>() + bids.numel()),
        std::vector<int32_t>(ids.data_ptr<int64_t>(), ids.data_ptr<int64_t>() + N_a));
    const at::Tensor nearest_ids = at::tensor(std::vector<int64_t>(nearest.begin(), nearest.end()), at::kLong);
    to_body = Vc.index_select(0, nearest_ids) - A_rest;
    if (body_weights.defined()) {
      TORCH_CHECK(body_weights.dim() == 2 && body_weights.size(0) == body_ids.size(0),
                  "apparel_graph: body_weights must be (", body_ids.size(0), ", J), got ", body_weights.sizes());
      g.contact_rest = Vc.index_select(0, nearest_ids).contiguous();
      g.contact_weights = body_weights.to(at::kFloat)
                              .index_select(0, body_rows(body_ids, std::vector<int64_t>(nearest.begin(), nearest.end())))
                              .contiguous();
    }
  }
  const Attachment a = attachments(V, edges, apparel_ids, body_ids);  // once for both uses
  g.rest_features = at::cat({to_joint, to_body, at::tensor(a.distance, at::kFloat).unsqueeze(1)}, 1).contiguous();
  g.ancestors = ancestors_of(a, kApparelReachLevels);
  return g;
}

// === Detail vectors and the zero-network rules

at::Tensor detail_vectors(const at::Tensor& A, const at::Tensor& S, const at::Tensor& transforms,
                          const at::Tensor& frame_joints) {
  const at::Tensor R = transforms.narrow(-1, 0, 3).index_select(-3, frame_joints);  // (..., N_a, 3, 3)
  return to_frame(R, A - S);
}

at::Tensor detail_rule_step(const at::Tensor& history, const at::Tensor& transforms, const at::Tensor& anchors,
                            const at::Tensor& frame_joints, double inertia) {
  const at::Tensor R = vertex_rotations(transforms, frame_joints);
  const std::vector<at::Tensor> d = history_details(history, anchors, R);
  const at::Tensor d_t = inertia == 0.0 ? d[2] : d[2] + inertia * (d[2] - d[1]);
  return anchors.select(1, 3) + from_frame(R.select(1, 3), d_t);
}

void InertiaFit::add(const at::Tensor& d) {
  if (d.size(0) < 3) return;
  const at::Tensor dd = (d.narrow(0, 1, d.size(0) - 1) - d.narrow(0, 0, d.size(0) - 1)).to(at::kDouble);
  const at::Tensor next = dd.narrow(0, 1, dd.size(0) - 1), last = dd.narrow(0, 0, dd.size(0) - 1);
  numerator += (next * last).sum().item<double>();
  denominator += (last * last).sum().item<double>();
}

double InertiaFit::inertia() const {
  if (!(denominator > 0)) return 0.0;
  return std::clamp(numerator / denominator, 0.0, 1.0);
}

// === Normaliser

RunningNormalizerImpl::RunningNormalizerImpl(int64_t channels, bool centred) : channels_(channels), centred_(centred) {
  TORCH_CHECK(channels > 0, "RunningNormalizer: channels must be positive");
  mean = register_buffer("mean", at::zeros({channels}, at::kFloat));
  scale = register_buffer("scale", at::ones({channels}, at::kFloat));
  count_ = register_buffer("count", at::zeros({1}, at::kDouble));
  sum_ = register_buffer("sum", at::zeros({channels}, at::kDouble));
  sum_squares_ = register_buffer("sum_squares", at::zeros({channels}, at::kDouble));
  frozen_ = register_buffer("frozen", at::zeros({1}, at::kDouble));
}

void RunningNormalizerImpl::accumulate(const at::Tensor& x) {
  TORCH_CHECK(!frozen(), "RunningNormalizer: accumulate after freeze");
  TORCH_CHECK(x.size(-1) == channels_, "RunningNormalizer: expected ", channels_, " channels, got ", x.sizes());
  torch::NoGradGuard no_grad;
  const at::Tensor rows = x.detach().reshape({-1, channels_}).to(at::kDouble);
  count_ += static_cast<double>(rows.size(0));
  sum_ += rows.sum(0);
  sum_squares_ += (rows * rows).sum(0);
}

void RunningNormalizerImpl::freeze() {
  torch::NoGradGuard no_grad;
  const double n = count();
  if (n > 0) {
    const at::Tensor m = centred_ ? sum_ / n : at::zeros_like(sum_);
    const at::Tensor var = (sum_squares_ / n - m * m).clamp_min(0.0);
    mean.copy_(m);
    scale.copy_(var.sqrt().clamp_min(kMinScale));
  }
  frozen_.fill_(1.0);
}

bool RunningNormalizerImpl::frozen() const { return frozen_.item<double>() != 0.0; }
double RunningNormalizerImpl::count() const { return count_.item<double>(); }

at::Tensor RunningNormalizerImpl::normalize(const at::Tensor& x) const { return (x - mean) / scale; }
at::Tensor RunningNormalizerImpl::denormalize(const at::Tensor& x) const { return x * scale + mean; }

at::Tensor apparel_anchor_weights_for(const std::string& anchor, const at::Tensor& V, const at::Tensor& edges,
                                      const at::Tensor& apparel_ids, const at::Tensor& body_ids,
                                      const at::Tensor& body_weights) {
  if (anchor == "attachment") return attachment_anchor_weights(V, edges, apparel_ids, body_ids, body_weights);
  AMT_CHECK(anchor == "nearest", "apparel anchor: expected attachment or nearest, found '", anchor, "'");
  return apparel_anchor_weights(V, apparel_ids, body_ids, body_weights);
}

// === The module

ApparelDynamicsNetImpl::ApparelDynamicsNetImpl(ApparelDynamicsOptions options_) : options(std::move(options_)) {
  TORCH_CHECK(options.form == "local", "ApparelDynamicsNet: form must be \"local\", got \"", options.form, "\"");
  TORCH_CHECK(options.num_joints > 0, "ApparelDynamicsNet: num_joints must be positive");
  TORCH_CHECK(!options.edge_widths.empty(), "ApparelDynamicsNet: needs at least one EdgeConv block");
  TORCH_CHECK(options.inertia >= 0.0 && options.inertia <= 1.0, "ApparelDynamicsNet: inertia must be in [0, 1]");
  TORCH_CHECK(options.reach_levels >= 0 && options.reach_levels <= kApparelReachLevels,
              "ApparelDynamicsNet: reach_levels must be in [0, ", kApparelReachLevels, "]");
  input_normalizer = register_module("input_normalizer", RunningNormalizer(channels(), /*centred=*/true));
  target_normalizer = register_module("target_normalizer", RunningNormalizer(3, /*centred=*/false));
  int64_t width = channels();
  for (size_t l = 0; l < options.edge_widths.size(); ++l) {
    EdgeConvOptions block(width, options.edge_widths[l]);
    block.negative_slope = options.negative_slope;
    block.naive = options.naive_edge_conv;
    blocks_.push_back(register_module("edge_conv" + std::to_string(l), EdgeConv(block)));
    width = options.edge_widths[l];
  }
  std::vector<int64_t> decoder = {width};
  decoder.insert(decoder.end(), options.decoder_widths.begin(), options.decoder_widths.end());
  decoder.push_back(3);
  MlpOptions decoder_options(decoder);
  decoder_options.negative_slope = options.negative_slope;
  decoder_options.zero_last = true;  // a fresh network is the rule
  decoder_ = register_module("decoder", Mlp(decoder_options));
}

at::Tensor ApparelDynamicsNetImpl::features(const at::Tensor& h, const at::Tensor& T, const at::Tensor& S,
                                            const ApparelGraph& g) const {
  check_inputs(h, T, S, g, options.num_joints, options.contact, options.reach_levels, "ApparelDynamicsNet");
  return features_from(h, T, S, g, vertex_rotations(T, g.frame_joints));
}

at::Tensor ApparelDynamicsNetImpl::features_from(const at::Tensor& h, const at::Tensor& T, const at::Tensor& S,
                                                 const ApparelGraph& g, const at::Tensor& R) const {
  const int64_t B = h.size(0), N = h.size(2);
  const at::Tensor R1 = R.select(1, 2);  // the frame at t-1
  const std::vector<at::Tensor> d = history_details(h, S, R);
  // Per joint, then gathered: the rotations over the last two steps and gravity at t.
  const at::Tensor Rj = T.narrow(-1, 0, 3);  // (B, 4, J, 3, 3)
  const auto turn = [&](int64_t a, int64_t b) {
    return axial(at::matmul(Rj.select(1, a).transpose(-1, -2), Rj.select(1, b))).index_select(1, g.frame_joints);
  };
  const at::Tensor gravity = -Rj.select(1, 3).select(-2, 1).index_select(1, g.frame_joints);  // R_t^T (0, -1, 0)
  const at::Tensor Sm = S.narrow(1, 1, 3) - S.narrow(1, 0, 3);  // (B, 3, N_a, 3): S_{k+1} - S_k
  std::vector<at::Tensor> channels = {d[2], d[2] - d[1], d[1] - d[0],
                                      to_frame(R1, Sm.select(1, 2)), to_frame(R1, Sm.select(1, 1)),
                                      to_frame(R1, Sm.select(1, 0)), to_frame(R1, h.select(1, 2) - h.select(1, 1)),
                                      turn(2, 3), turn(1, 2), gravity,
                                      g.rest_features.unsqueeze(0).expand({B, N, kApparelRestChannels})};
  if (options.contact) {
    const at::Tensor P_last = contact_points(g.contact_rest, g.contact_weights, T.select(1, 2));
    const at::Tensor P_next = contact_points(g.contact_rest, g.contact_weights, T.select(1, 3));
    channels.push_back(to_frame(R1, P_next - h.select(1, 2)));
    channels.push_back(to_frame(R1, P_next - P_last));
  }
  if (options.response) {
    channels.push_back(g.response.defined()
                           ? g.response.to(h.scalar_type()).unsqueeze(0).expand({B, N, kApparelResponseChannels})
                           : at::zeros({B, N, kApparelResponseChannels}, h.options()));
  }
  return at::cat(channels, 2);
}

at::Tensor ApparelDynamicsNetImpl::rule_detail(const at::Tensor& d_last, const at::Tensor& d_before) const {
  return options.inertia == 0.0 ? d_last : d_last + options.inertia * (d_last - d_before);
}

at::Tensor ApparelDynamicsNetImpl::step(const at::Tensor& history, const at::Tensor& transforms,
                                        const at::Tensor& anchors, const ApparelGraph& g, at::Tensor* detail) {
  const bool unbatched = history.dim() == 3;
  const at::Tensor h = batched(history, 3), T = batched(transforms, 4), S = batched(anchors, 3);
  check_inputs(h, T, S, g, options.num_joints, options.contact, options.reach_levels, "ApparelDynamicsNet");
  // Without autograd (inference) the features and the output come from the fused per-vertex loops.
  const bool fused = !at::GradMode::is_enabled() && fused_inputs(h, T, S, g);
  at::Tensor R, x, D;  // D: the raw first six channels
  if (fused) {
    x = fused_features(h, T, S, g, options.contact, options.response, channels(), input_normalizer->mean,
                       input_normalizer->scale, D);
  } else {
    R = vertex_rotations(T, g.frame_joints);
    const at::Tensor H = features_from(h, T, S, g, R);
    x = input_normalizer->normalize(H);
    D = H.narrow(2, 0, 6);
  }
  // The mesh neighbours, and with reach levels the chain's ancestors 1, 2, 4, ... hops towards the body.
  const at::Tensor neighbors =
      options.reach_levels > 0 ? at::cat({g.neighbors, g.ancestors.narrow(1, 0, options.reach_levels)}, 1) : g.neighbors;
  for (EdgeConv& block : blocks_) x = block->forward(x, neighbors);  // eq. (13)
  const at::Tensor change = target_normalizer->denormalize(decoder_->forward(x));
  // d_{t-1} and d_{t-2} are the first input channels (d_{t-1}, d_{t-1} - d_{t-2}).
  const at::Tensor d_last = D.narrow(2, 0, 3);
  const at::Tensor d_t = rule_detail(d_last, d_last - D.narrow(2, 3, 3)) + change;
  const at::Tensor A_t =
      fused ? fused_output(T, S, d_t.contiguous(), g.frame_joints) : S.select(1, 3) + from_frame(R.select(1, 3), d_t);
  if (detail) *detail = unbatched ? d_t.squeeze(0) : d_t;
  return unbatched ? A_t.squeeze(0) : A_t;
}

at::Tensor ApparelDynamicsNetImpl::rollout(const at::Tensor& initial, const at::Tensor& transforms,
                                           const at::Tensor& anchors, const ApparelGraph& g) {
  const bool unbatched = initial.dim() == 3;
  at::Tensor history = batched(initial, 3);
  const at::Tensor T = batched(transforms, 4), S = batched(anchors, 3);
  TORCH_CHECK(T.dim() == 5 && S.dim() == 4 && T.size(1) == S.size(1) && T.size(1) > 3,
              "ApparelDynamicsNet::rollout: transforms and anchors must cover the 3 initial frames and at least one "
              "more, got ", transforms.sizes(), " and ", anchors.sizes());
  const int64_t frames = T.size(1) - 3;
  std::vector<at::Tensor> out;
  out.reserve(static_cast<size_t>(frames));
  for (int64_t t = 0; t < frames; ++t) {
    const at::Tensor next = step(history, T.narrow(1, t, 4), S.narrow(1, t, 4), g);
    out.push_back(next);
    history = at::cat({history.narrow(1, 1, 2), next.unsqueeze(1)}, 1);
  }
  const at::Tensor stacked = at::stack(out, 1);
  return unbatched ? stacked.squeeze(0) : stacked;
}

void ApparelDynamicsNetImpl::observe(const at::Tensor& history, const at::Tensor& transforms,
                                     const at::Tensor& anchors, const ApparelGraph& g, const at::Tensor& target) {
  torch::NoGradGuard no_grad;
  const at::Tensor h = batched(history, 3), T = batched(transforms, 4), S = batched(anchors, 3);
  const at::Tensor A = batched(target, 2);
  input_normalizer->accumulate(features(h, T, S, g));
  const at::Tensor R = vertex_rotations(T, g.frame_joints);
  const at::Tensor d_last = to_frame(R.select(1, 2), h.select(1, 2) - S.select(1, 2));
  const at::Tensor d_before = to_frame(R.select(1, 1), h.select(1, 1) - S.select(1, 1));
  const at::Tensor d_target = to_frame(R.select(1, 3), A - S.select(1, 3));
  target_normalizer->accumulate(d_target - rule_detail(d_last, d_before));
}

void ApparelDynamicsNetImpl::freeze_normalizers() {
  input_normalizer->freeze();
  target_normalizer->freeze();
}

void ApparelDynamicsNetImpl::widen_from(ApparelDynamicsNetImpl& source) {
  ApparelDynamicsOptions expected = source.options;
  expected.response = true;
  AMT_CHECK(!source.options.response && options.response && options_to_json(expected) == options_to_json(options),
            "apparel module: widen: expected a module without physics inputs and one alike with them");
  torch::NoGradGuard no_grad;
  const int64_t C = source.channels(), extra = channels() - C;
  // Every tensor of the same shape is copied; the others get the new channels by `widen(key, old, target)`.
  const auto copy = [](const torch::OrderedDict<std::string, at::Tensor>& to,
                       const torch::OrderedDict<std::string, at::Tensor>& from, const auto& widen) {
    for (const auto& item : to) {
      const at::Tensor& old = from[item.key()];
      at::Tensor target = item.value();
      if (old.sizes() == target.sizes()) {
        target.copy_(old);
      } else {
        widen(item.key(), old, target);
      }
    }
  };
  // The first block's edge layer (C_out, 2 C) = [W1 | W2] on [h_i, h_j - h_i]: zero columns after each half.
  copy(named_parameters(), source.named_parameters(),
       [&](const std::string& key, const at::Tensor& old, at::Tensor& target) {
         AMT_CHECK(key == "edge_conv0.edge.weight" && old.dim() == 2 && old.size(1) == 2 * C,
                   "apparel module: widen: unexpected shape of ", key);
         target.zero_();
         target.narrow(1, 0, C).copy_(old.narrow(1, 0, C));
         target.narrow(1, C + extra, C).copy_(old.narrow(1, C, C));
       });
  // The input normaliser: the new channels at mean 0, scale 1.
  copy(named_buffers(), source.named_buffers(), [&](const std::string& key, const at::Tensor& old, at::Tensor& target) {
    AMT_CHECK(old.dim() == 1 && target.dim() == 1 && target.size(0) == C + extra && old.size(0) == C,
              "apparel module: widen: unexpected shape of ", key);
    const bool is_scale = key.size() >= 5 && key.compare(key.size() - 5, 5, "scale") == 0;
    target.fill_(is_scale ? 1.0 : 0.0);
    target.narrow(0, 0, C).copy_(old);
  });
}

bool ApparelDynamicsNetImpl::normalizers_frozen() const {
  return input_normalizer->frozen() && target_normalizer->frozen();
}

}  // namespace amt
