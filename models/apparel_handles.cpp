#include "models/apparel_handles.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <torch/utils.h>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <vector>

#include "data_tools/geometry/error.h"
#include "models/edge_conv.h"

namespace amt {

HandleOptions handle_options(double spacing) {
  HandleOptions o;
  o.spacing = static_cast<float>(spacing);
  o.radius = static_cast<float>(2.25 * spacing);
  o.max_handles = 4;
  return o;
}

namespace {

// The tensors of a rig of handles over N_a apparel vertices.
ApparelRig rig_tensors(const ApparelHandles& h, int64_t N_a) {
  ApparelRig rig;
  const int64_t K = h.vertex_handles.cols();
  rig.rows = at::tensor(std::vector<int64_t>(h.handles.begin(), h.handles.end()), at::kLong);
  rig.vertex_handles =
      at::from_blob(const_cast<int32_t*>(h.vertex_handles.data()), {N_a, K}, at::kInt).to(at::kLong).contiguous();
  rig.vertex_weights = at::from_blob(const_cast<float*>(h.vertex_weights.data()), {N_a, K}, at::kFloat).clone();
  rig.edges = h.handle_edges.rows() > 0
                  ? at::from_blob(const_cast<int32_t*>(h.handle_edges.data()), {h.handle_edges.rows(), 2}, at::kInt)
                        .to(at::kLong)
                        .contiguous()
                  : at::zeros({0, 2}, at::kLong);
  return rig;
}

MatrixX3f eigen_vertices(const at::Tensor& V) {
  const at::Tensor Vc = V.to(at::kFloat).contiguous();
  return Eigen::Map<const MatrixX3f>(Vc.data_ptr<float>(), Vc.size(0), 3);
}

std::vector<int32_t> id_list(const at::Tensor& ids) {
  const at::Tensor c = ids.to(at::kInt).contiguous();
  return std::vector<int32_t>(c.data_ptr<int32_t>(), c.data_ptr<int32_t>() + c.numel());
}

}  // namespace

ApparelRig apparel_rig(const at::Tensor& V, const at::Tensor& edges, const at::Tensor& apparel_ids,
                       const at::Tensor& body_ids, const HandleOptions& options) {
  torch::NoGradGuard no_grad;
  const at::Tensor E = edges.to(at::kInt).contiguous();
  const MatrixX2i E_e = Eigen::Map<const MatrixX2i>(E.data_ptr<int32_t>(), E.size(0), 2);
  const at::Tensor hang = attachment_distances(V, edges, apparel_ids, body_ids).contiguous();
  const std::vector<float> distance(hang.data_ptr<float>(), hang.data_ptr<float>() + hang.numel());
  return rig_tensors(apparel_handles(eigen_vertices(V), E_e, id_list(apparel_ids), distance, options),
                     apparel_ids.size(0));
}

ApparelRig bone_rig(const at::Tensor& V, const at::Tensor& apparel_ids, const ApparelBones& bones, int max_handles) {
  torch::NoGradGuard no_grad;
  return rig_tensors(bone_handles(eigen_vertices(V), id_list(apparel_ids), bones, max_handles), apparel_ids.size(0));
}

ApparelGraph handle_graph(const ApparelGraph& g, const ApparelRig& rig) {
  AMT_CHECK(rig.defined(), "handle graph: the character has no handles");
  const at::Tensor& r = rig.rows;
  ApparelGraph h;
  h.neighbors = neighbor_table(rig.num_handles(), rig.edges);
  h.frame_joints = g.frame_joints.index_select(0, r).contiguous();
  h.rest_features = g.rest_features.index_select(0, r).contiguous();
  if (g.contact_rest.defined()) h.contact_rest = g.contact_rest.index_select(0, r).contiguous();
  if (g.contact_weights.defined()) h.contact_weights = g.contact_weights.index_select(0, r).contiguous();
  if (g.response.defined()) h.response = g.response.index_select(0, r).contiguous();
  if (g.ancestors.defined()) {
    // Each ancestor vertex's nearest handle (its first, heaviest-nearest column).
    const at::Tensor nearest = rig.vertex_handles.select(1, 0);
    const at::Tensor a = g.ancestors.index_select(0, r);
    h.ancestors = nearest.index_select(0, a.flatten()).view(a.sizes()).contiguous();
  }
  return h;
}

at::Tensor follow_handles(const at::Tensor& A_h, const at::Tensor& S_h, const at::Tensor& S, const ApparelRig& rig) {
  AMT_CHECK(rig.defined(), "follow handles: the character has no handles");
  const int64_t N_a = rig.vertex_handles.size(0), K = rig.vertex_handles.size(1);
  AMT_CHECK(S.size(-2) == N_a && A_h.size(-2) == rig.num_handles() && S_h.sizes() == A_h.sizes(),
            "follow handles: expected ", rig.num_handles(), " handles and ", N_a, " vertices, found handles ",
            A_h.sizes(), ", anchors ", S_h.sizes(), " and ", S.sizes());
  const at::Tensor offsets = A_h - S_h;                                                // (..., H, 3)
  const at::Tensor gathered = offsets.index_select(-2, rig.vertex_handles.flatten());  // (..., N_a K, 3)
  std::vector<int64_t> shape(gathered.sizes().begin(), gathered.sizes().end());
  shape[shape.size() - 2] = N_a;
  shape.insert(shape.end() - 1, K);
  const at::Tensor w = rig.vertex_weights.unsqueeze(-1);  // (N_a, K, 1)
  return S + (gathered.view(shape) * w).sum(-2);
}

namespace {
// The pull towards no turn, relative to the neighbours' squared offsets: a chain whose handles stray from one line
// by less than about this share of their spacing turns as a straight chain (no twist); a piece turned as a whole
// turns by a few thousandths less than it did.
constexpr double kTurnPull = 1e-3;

// The rotation closest to m (3 x 3, non-singular: the pull keeps it so), U diag(1, 1, det) V^T of its singular value
// decomposition, from the eigen decomposition of m^T m (V, and U = m V / sigma): under a microsecond, for every handle
// of every frame, where an iterative SVD takes several times that. Eigen's iterative symmetric solver, not its
// closed-form one (computeDirect, about 0.15 us against 0.6): the closed form loses its eigenvectors' precision where
// eigenvalues lie close together (a handle whose neighbours barely move), and the stepper and a rollout of the same
// handles differed by 0.03-0.05 mm on one CPU and agreed on another.
Eigen::Matrix3d rotation_part(const Eigen::Matrix3d& m) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen;
  eigen.compute(m.transpose() * m);
  const Eigen::Vector3d lambda = eigen.eigenvalues();  // ascending
  if (!(lambda(0) > 1e-24 * lambda(2))) {
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
    d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
    return svd.matrixU() * d * svd.matrixV().transpose();
  }
  const Eigen::Matrix3d& V = eigen.eigenvectors();
  Eigen::Matrix3d U = m * V;
  for (int c = 0; c < 3; ++c) U.col(c) /= std::sqrt(lambda(c));
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  if (m.determinant() < 0.0) d(0, 0) = -1.0;  // the smallest singular value's direction flips
  return U * d * V.transpose();
}

at::Tensor handle_turn_share(const at::Tensor& A_h, const at::Tensor& S_h, const at::Tensor& S, const ApparelRig& rig);
}  // namespace

at::Tensor handle_turns(const at::Tensor& A_h, const at::Tensor& S_h, const ApparelRig& rig) {
  AMT_CHECK(rig.defined(), "handle turns: the character has no handles");
  const int64_t H = rig.num_handles();
  AMT_CHECK(A_h.dim() >= 2 && A_h.size(-2) == H && A_h.size(-1) == 3 && S_h.sizes() == A_h.sizes(),
            "handle turns: expected (..., ", H, ", 3) handles and anchors, found ", A_h.sizes(), " and ", S_h.sizes());
  torch::NoGradGuard no_grad;
  const at::Tensor A = A_h.detach().to(at::kFloat).reshape({-1, H, 3}).contiguous();
  const at::Tensor S = S_h.detach().to(at::kFloat).reshape({-1, H, 3}).contiguous();
  const at::Tensor E = rig.edges.to(at::kLong).contiguous();
  const int64_t B = A.size(0), n_edges = E.size(0);
  std::vector<int64_t> sizes(A_h.sizes().begin(), A_h.sizes().end());
  sizes.push_back(3);
  at::Tensor R = at::empty({B, H, 3, 3}, at::kFloat);
  const float* a = A.data_ptr<float>();
  const float* s = S.data_ptr<float>();
  const int64_t* e = E.data_ptr<int64_t>();
  float* r = R.data_ptr<float>();
  // Written out: a few hundred 3x3 decompositions per frame, where a batched LAPACK call costs more in overhead.
  // The neighbours' covariance per handle (a pass over the edges), then each handle's turn on its own.
  std::vector<Eigen::Matrix3d> cov(static_cast<size_t>(B * H), Eigen::Matrix3d::Zero());
  std::vector<double> scale(static_cast<size_t>(B * H), 0.0);
  std::vector<uint8_t> turned(static_cast<size_t>(B * H), 0);
  at::parallel_for(0, B, 1, [&](int64_t b0, int64_t b1) {
    for (int64_t b = b0; b < b1; ++b) {
      const float* ab = a + b * H * 3;
      const float* sb = s + b * H * 3;
      const size_t base = static_cast<size_t>(b * H);
      for (int64_t k = 0; k < n_edges; ++k) {
        const size_t i = static_cast<size_t>(e[2 * k]), j = static_cast<size_t>(e[2 * k + 1]);
        const Eigen::Vector3d da(ab[3 * j] - ab[3 * i], ab[3 * j + 1] - ab[3 * i + 1], ab[3 * j + 2] - ab[3 * i + 2]);
        const Eigen::Vector3d ds(sb[3 * j] - sb[3 * i], sb[3 * j + 1] - sb[3 * i + 1], sb[3 * j + 2] - sb[3 * i + 2]);
        const Eigen::Matrix3d outer = da * ds.transpose();  // the same seen from either end
        cov[base + i] += outer;
        cov[base + j] += outer;
        scale[base + i] += ds.squaredNorm();
        scale[base + j] += ds.squaredNorm();
        if (da != ds) turned[base + i] = turned[base + j] = 1;
      }
    }
  });
  at::parallel_for(0, B * H, 64, [&](int64_t k0, int64_t k1) {
    for (int64_t k = k0; k < k1; ++k) {
      Eigen::Matrix3d turn = Eigen::Matrix3d::Identity();
      // Neighbours exactly where their anchors put them: no turn, exactly (the anchor skinning is kept bit for bit).
      if (turned[size_t(k)] && scale[size_t(k)] > 0.0)
        turn = rotation_part(cov[size_t(k)] + kTurnPull * scale[size_t(k)] * Eigen::Matrix3d::Identity());
      float* out = r + k * 9;
      for (int x = 0; x < 3; ++x)
        for (int y = 0; y < 3; ++y) out[3 * x + y] = static_cast<float>(turn(x, y));
    }
  });
  return R.view(sizes);
}

at::Tensor follow_turning_handles(const at::Tensor& A_h, const at::Tensor& S_h, const at::Tensor& S,
                                  const ApparelRig& rig) {
  const at::Tensor moved = follow_handles(A_h, S_h, S, rig);
  return moved + handle_turn_share(A_h, S_h, S, rig).view(moved.sizes()).to(moved.scalar_type());
}

namespace {

// The turns' share of follow_turning_handles, held fixed: sum_k w_k (R_k - I) (S_v - S_h[k]), (B, N_a, 3).
at::Tensor handle_turn_share(const at::Tensor& A_h, const at::Tensor& S_h, const at::Tensor& S, const ApparelRig& rig) {
  const int64_t N_a = rig.vertex_handles.size(0), K = rig.vertex_handles.size(1), H = rig.num_handles();
  torch::NoGradGuard no_grad;
  const at::Tensor R = handle_turns(A_h, S_h, rig).reshape({-1, H, 3, 3}).contiguous();
  const at::Tensor Sh = S_h.detach().to(at::kFloat).reshape({-1, H, 3}).contiguous();
  const at::Tensor Sv = S.detach().to(at::kFloat).reshape({-1, N_a, 3}).contiguous();
  const at::Tensor idx = rig.vertex_handles.to(at::kLong).contiguous();
  const at::Tensor w = rig.vertex_weights.to(at::kFloat).contiguous();
  const int64_t B = R.size(0);
  at::Tensor turn = at::zeros({B, N_a, 3}, at::kFloat);
  const float* r = R.data_ptr<float>();
  const float* sh = Sh.data_ptr<float>();
  const float* sv = Sv.data_ptr<float>();
  const int64_t* ix = idx.data_ptr<int64_t>();
  const float* wx = w.data_ptr<float>();
  float* out = turn.data_ptr<float>();
  at::parallel_for(0, B * N_a, 2048, [&](int64_t i0, int64_t i1) {
    for (int64_t i = i0; i < i1; ++i) {
      const int64_t b = i / N_a, v = i % N_a;
      const float* p = sv + i * 3;
      float acc[3] = {0.0f, 0.0f, 0.0f};
      for (int64_t k = 0; k < K; ++k) {
        const float wk = wx[v * K + k];
        if (wk == 0.0f) continue;
        const int64_t h = ix[v * K + k];
        const float* q = sh + (b * H + h) * 3;
        const float d[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
        const float* m = r + (b * H + h) * 9;
        for (int x = 0; x < 3; ++x) acc[x] += wk * (m[3 * x] * d[0] + m[3 * x + 1] * d[1] + m[3 * x + 2] * d[2] - d[x]);
      }
      for (int x = 0; x < 3; ++x) out[i * 3 + x] = acc[x];
    }
  });
  return turn;
}

}  // namespace

at::Tensor apparel_response(const Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& indices,
                            const MatrixXfR& weights, const MatrixXfR& bone_response, const at::Tensor& apparel_ids) {
  const at::Tensor ids = apparel_ids.to(at::kLong).contiguous();
  const std::vector<int32_t> list(ids.data_ptr<int64_t>(), ids.data_ptr<int64_t>() + ids.numel());
  const MatrixXfR r = vertex_response(indices, weights, bone_response, list);
  return at::from_blob(const_cast<float*>(r.data()), {r.rows(), r.cols()}, at::kFloat).clone();
}

}  // namespace amt
