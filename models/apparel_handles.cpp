#include "models/apparel_handles.h"

#include <ATen/ATen.h>
#include <torch/utils.h>

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

at::Tensor apparel_response(const Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& indices,
                            const MatrixXfR& weights, const MatrixXfR& bone_response, const at::Tensor& apparel_ids) {
  const at::Tensor ids = apparel_ids.to(at::kLong).contiguous();
  const std::vector<int32_t> list(ids.data_ptr<int64_t>(), ids.data_ptr<int64_t>() + ids.numel());
  const MatrixXfR r = vertex_response(indices, weights, bone_response, list);
  return at::from_blob(const_cast<float*>(r.data()), {r.rows(), r.cols()}, at::kFloat).clone();
}

}  // namespace amt
