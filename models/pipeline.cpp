#include "models/pipeline.h"

#include <ATen/ATen.h>
#include <c10/core/InferenceMode.h>
#include <torch/utils.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <numeric>
#include <sstream>

#include "data_tools/geometry/apparel_topology.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/geodesic.h"
#include "data_tools/geometry/lbs_torch.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/motion.h"
#include "data_tools/geometry/segmentation_features.h"
#include "data_tools/geometry/skeleton.h"
#include "models/edge_conv.h"
#include "models/module_options.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

const char* variant_name(SkinningVariant variant) {
  switch (variant) {
    case SkinningVariant::kGeodesicAttention:
      return "geodesic attention";
    case SkinningVariant::kNoGeodesic:
      return "no geodesic";
    case SkinningVariant::kSortByGeodesic:
      return "sort by geodesic";
  }
  return "?";
}

std::string joined(const std::vector<std::string>& names) {
  std::ostringstream out;
  for (size_t i = 0; i < names.size() && i < 4; ++i) out << (i ? ", " : "") << names[i];
  if (names.size() > 4) out << ", ...";
  return out.str();
}

void check_joints_option(const std::string& path, int64_t num_joints, int64_t J) {
  AMT_CHECK(num_joints == J, path, ": options.num_joints: expected ", J, " (the skeleton's joint names), found ",
            num_joints);
}

MatrixX3f to_matrix3f(const at::Tensor& t) {
  const at::Tensor c = t.to(at::kFloat).contiguous();
  return Eigen::Map<const MatrixX3f>(c.data_ptr<float>(), c.size(0), 3);
}

MatrixX3i to_matrix3i(const at::Tensor& t) {
  const at::Tensor c = t.to(at::kInt).contiguous();
  return Eigen::Map<const MatrixX3i>(c.data_ptr<int32_t>(), c.size(0), 3);
}

at::Tensor from_matrix(const MatrixXfR& m) {
  return at::from_blob(const_cast<float*>(m.data()), {m.rows(), m.cols()}, at::kFloat).clone();
}

at::Tensor edge_tensor(const MatrixX2i& E) {
  if (E.rows() == 0) return at::zeros({0, 2}, at::kLong);
  return at::from_blob(const_cast<int32_t*>(E.data()), {E.rows(), 2}, at::kInt).to(at::kLong);
}

// welded_geodesics of the vertices `ids` (int64 tensor) as a (N_s, J) float tensor.
at::Tensor welded_geodesics_tensor(const MatrixX3f& V, const MatrixX3i& F, const MatrixX3f& joints,
                                   const at::Tensor& ids, const std::vector<int32_t>& canon, const char* what) {
  const at::Tensor id = ids.to(at::kInt).contiguous();
  const std::vector<int32_t> list(id.data_ptr<int32_t>(), id.data_ptr<int32_t>() + id.numel());
  return from_matrix(welded_geodesics(V, F, joints, list, canon, what));
}

std::vector<uint8_t> mask_vector(const at::Tensor& mask) {
  const at::Tensor m = mask.to(at::kByte).contiguous();
  return std::vector<uint8_t>(m.data_ptr<uint8_t>(), m.data_ptr<uint8_t>() + m.numel());
}

at::Tensor mask_tensor(const std::vector<uint8_t>& mask) {
  return at::tensor(at::ArrayRef<uint8_t>(mask), at::kByte).to(at::kBool);
}

// Rows (N_a, ...) over the apparel vertices apparel_ids with each vertex's row replaced by its canonical copy's
// (canonical_copies): ties in the graph searches cannot give coincident copies different anchors or handles.
at::Tensor canonical_rows(const at::Tensor& rows, const at::Tensor& apparel_ids, const std::vector<int32_t>& canon) {
  const at::Tensor ids = apparel_ids.to(at::kLong).contiguous();
  const int64_t* first = ids.data_ptr<int64_t>();
  const int64_t n = ids.numel();
  std::vector<int64_t> source(static_cast<size_t>(n));
  for (int64_t k = 0; k < n; ++k) {
    const int64_t c = canon[size_t(first[k])];
    const int64_t* at = std::lower_bound(first, first + n, c);
    source[size_t(k)] = at != first + n && *at == c ? at - first : k;
  }
  return rows.index_select(0, at::tensor(source, at::kLong)).contiguous();
}

// The local apparel module's per-character inputs from the bound parts and anchor weights, and the physics
// response of the apparel bones when they carry one.
void set_apparel_graph(BoundCharacter& c, const ApparelBones* bones) {
  const ApparelGraph g = apparel_graph(c.V, c.graph_edges, c.apparel_ids, c.body_ids, c.apparel_anchor_weights,
                                       c.joints, c.apparel_neighbors, c.body_weights);
  c.apparel_frame_joints = g.frame_joints;
  c.apparel_rest_features = g.rest_features;
  c.apparel_contact_rest = g.contact_rest;
  c.apparel_contact_weights = g.contact_weights;
  c.apparel_ancestors = g.ancestors;
  c.apparel_response = at::Tensor();
  if (bones && bones->response.rows() > 0 && bones->indices.rows() == c.num_vertices())
    c.apparel_response = apparel_response(bones->indices, bones->weights, bones->response, c.apparel_ids);
}

}  // namespace

// === Model bundle

SkinningPredictor ModelBundle::skinning_for(SkinningVariant variant) const {
  const SkinningPredictor& net = variant == SkinningVariant::kGeodesicAttention ? skinning
                                 : variant == SkinningVariant::kNoGeodesic      ? skinning_no_geodesic
                                                                                : skinning_sorted;
  const char* file = variant == SkinningVariant::kGeodesicAttention ? kSkinningCheckpoint
                     : variant == SkinningVariant::kNoGeodesic      ? kSkinningNoGeodesicCheckpoint
                                                                    : kSkinningSortedCheckpoint;
  AMT_CHECK(!net.is_empty(), (dir.empty() ? std::string("model") : dir), "/", file, ": no such checkpoint (the ",
            variant_name(variant), " skinning variant was not loaded)");
  return net;
}

const torch::nn::Module* ModelBundle::apparel_module() const {
  return local_apparel() ? static_cast<const torch::nn::Module*>(apparel_dynamics.get())
                         : static_cast<const torch::nn::Module*>(apparel.get());
}

ModelBundle load_segmenter_bundle(const std::string& checkpoint) {
  std::error_code error;
  AMT_CHECK(fs::is_regular_file(checkpoint, error), checkpoint,
            ": no such checkpoint (train it with amt train segmenter)");
  ModelBundle bundle;
  CheckpointInfo info;
  bundle.segmenter =
      load_frozen_network<ApparelSegmenter, ApparelSegmenterOptions>(checkpoint, ModuleKind::kSegmenter, info);
  bundle.joint_names = info.joint_names;
  AMT_CHECK(!bundle.joint_names.empty(), checkpoint, ": joint_names: expected at least one joint, found none");
  bundle.infos.push_back(info);
  return bundle;
}

ModelBundle load_model_bundle(const std::string& dir) {
  std::error_code error;
  AMT_CHECK(fs::is_directory(dir, error), dir, ": no such model folder (expected a folder with ", kSegmenterCheckpoint,
            ", ", kSkinningCheckpoint, ", ", kApparelCheckpoint, ", ", kRefinerCheckpoint, ")");
  ModelBundle bundle;
  bundle.dir = dir;
  const auto path_of = [&](const char* file) { return (fs::path(dir) / file).string(); };
  const auto require = [&](const char* file, ModuleKind kind) {
    const std::string path = path_of(file);
    AMT_CHECK(fs::is_regular_file(path, error), path, ": no such checkpoint (train it with amt train ",
              module_kind_name(kind), ")");
    return path;
  };
  std::string first_path;
  const auto check_skeleton = [&](const std::string& path, const CheckpointInfo& info) {
    if (first_path.empty()) {
      first_path = path;
      bundle.joint_names = info.joint_names;
      AMT_CHECK(!bundle.joint_names.empty(), path, ": joint_names: expected at least one joint, found none");
      return;
    }
    AMT_CHECK(info.joint_names == bundle.joint_names, path, ": skeleton: trained on ", info.joint_names.size(),
              " joints (", joined(info.joint_names), "), but ", first_path, " on ", bundle.joint_names.size(), " (",
              joined(bundle.joint_names), "): all modules of a model must share one skeleton");
  };

  CheckpointInfo info;
  std::string path = require(kSegmenterCheckpoint, ModuleKind::kSegmenter);
  bundle.segmenter = load_frozen_network<ApparelSegmenter, ApparelSegmenterOptions>(path, ModuleKind::kSegmenter, info);
  check_skeleton(path, info);
  bundle.infos.push_back(info);
  const int64_t J = bundle.num_joints();

  path = require(kSkinningCheckpoint, ModuleKind::kSkinning);
  bundle.skinning = load_frozen_network<SkinningPredictor, SkinningPredictorOptions>(path, ModuleKind::kSkinning, info);
  check_skeleton(path, info);
  check_joints_option(path, bundle.skinning->options.num_joints, J);
  AMT_CHECK(bundle.skinning->options.variant == SkinningVariant::kGeodesicAttention, path,
            ": options.variant: expected the geodesic attention variant, found ",
            variant_name(bundle.skinning->options.variant));
  bundle.infos.push_back(info);

  // A local apparel module (apparel.ckpt or apparel_own_weights.ckpt): its joints, frozen normalisers.
  const auto load_local_apparel = [&](const std::string& file, CheckpointInfo& file_info) {
    ApparelDynamicsNet net =
        load_frozen_network<ApparelDynamicsNet, ApparelDynamicsOptions>(file, ModuleKind::kApparel, file_info);
    check_joints_option(file, net->options.num_joints, J);
    AMT_CHECK(net->normalizers_frozen(), file, ": input_normalizer: expected frozen statistics ",
              "(a checkpoint written after the normaliser warm-up), found none");
    return net;
  };
  path = require(kApparelCheckpoint, ModuleKind::kApparel);
  if (is_local_apparel_options(read_checkpoint_info(path, ModuleKind::kApparel).options_json)) {
    bundle.apparel_dynamics = load_local_apparel(path, info);
  } else {
    bundle.apparel =
        load_frozen_network<ApparelDisplacementNet, ApparelDisplacementOptions>(path, ModuleKind::kApparel, info);
    check_joints_option(path, bundle.apparel->options.num_joints, J);
  }
  check_skeleton(path, info);
  bundle.infos.push_back(info);

  path = require(kRefinerCheckpoint, ModuleKind::kRefiner);
  bundle.refiner = load_frozen_network<JointRefiner, JointRefinerOptions>(path, ModuleKind::kRefiner, info);
  check_skeleton(path, info);
  bundle.infos.push_back(info);

  const auto optional_variant = [&](const char* file, SkinningVariant variant, SkinningPredictor& out) {
    const std::string p = path_of(file);
    if (!fs::exists(p, error)) return;
    CheckpointInfo variant_info;
    out = load_frozen_network<SkinningPredictor, SkinningPredictorOptions>(p, ModuleKind::kSkinning, variant_info);
    check_skeleton(p, variant_info);
    check_joints_option(p, out->options.num_joints, J);
    AMT_CHECK(out->options.variant == variant, p, ": options.variant: expected the ", variant_name(variant),
              " variant (from the file name), found ", variant_name(out->options.variant));
  };
  const std::string own = path_of(kApparelOwnWeightsCheckpoint);
  if (fs::exists(own, error)) {
    AMT_CHECK(bundle.local_apparel(), own, ": expected it beside a local apparel module (", kApparelCheckpoint,
              " is the global form)");
    CheckpointInfo own_info;
    bundle.apparel_dynamics_own_weights = load_local_apparel(own, own_info);
    check_skeleton(own, own_info);
    const ApparelDynamicsOptions &a = bundle.apparel_dynamics->options,
                                 &b = bundle.apparel_dynamics_own_weights->options;
    AMT_CHECK(b.handle_spacing == a.handle_spacing && b.anchor == a.anchor, own, ": options: expected the handles (",
              a.handle_spacing, " m) and anchor (", a.anchor, ") of ", kApparelCheckpoint, ", found ", b.handle_spacing,
              " m and ", b.anchor);
  }
  optional_variant(kSkinningNoGeodesicCheckpoint, SkinningVariant::kNoGeodesic, bundle.skinning_no_geodesic);
  optional_variant(kSkinningSortedCheckpoint, SkinningVariant::kSortByGeodesic, bundle.skinning_sorted);
  return bundle;
}

void check_bundle_skeleton(const ModelBundle& bundle, const std::vector<std::string>& joint_names,
                           const std::string& source) {
  AMT_CHECK(joint_names == bundle.joint_names, source, ": skeleton: the model ",
            (bundle.dir.empty() ? std::string() : "(" + bundle.dir + ") "), "was trained on ",
            bundle.joint_names.size(), " joints (", joined(bundle.joint_names), "), this has ", joint_names.size(),
            " (", joined(joint_names), ")");
}

// === Bind

at::Tensor apparel_probabilities(const ModelBundle& bundle, const MatrixX3f& V, const MatrixX3i& F,
                                 const MatrixX3f& joints) {
  torch::NoGradGuard no_grad;
  at::Tensor shape_features;
  if (segmenter_feature_channels(bundle.segmenter->options) > 0) {
    // The bundle knows its joints by name: the canonical skeleton's bones, or (a model trained on
    // another skeleton) distances to the joints themselves.
    const std::vector<int32_t> parents = bundle.joint_names == canonical_joint_names()
                                             ? canonical_joint_parents()
                                             : std::vector<int32_t>(static_cast<size_t>(joints.rows()), -1);
    shape_features = from_matrix(segmenter_input_features(bundle.segmenter->options.inputs, V, F, joints, parents));
  }
  const at::Tensor V_t = at::from_blob(const_cast<float*>(V.data()), {V.rows(), 3}, at::kFloat);
  return bundle.segmenter.ptr()->probabilities(V_t, shape_features).contiguous();
}

at::Tensor hang_apparel_pieces(const at::Tensor& mask, const at::Tensor& prob, const MatrixX2i& edges, double share,
                               HungPieces* hung) {
  const int64_t N = mask.size(0);
  AMT_CHECK(mask.dim() == 1 && prob.dim() == 1 && prob.size(0) == N, "hang_apparel_pieces: expected (N) mask and ",
            "(N) probabilities, found ", mask.sizes(), " and ", prob.sizes());
  AMT_CHECK(share > 0 && share <= 1, "hang_apparel_pieces: share: expected (0, 1], found ", share);
  at::Tensor out = mask.to(at::kBool).contiguous().clone();
  const at::Tensor p = prob.to(at::kFloat).contiguous();
  bool* m = out.data_ptr<bool>();
  const float* q = p.data_ptr<float>();
  if (hung) *hung = HungPieces{};
  if (std::all_of(m, m + N, [](bool a) { return a; })) return out;  // no body to hang from
  int count = 0;
  const std::vector<int32_t> part = connected_components(static_cast<int>(N), edges, &count);
  // Body islands: body vertices joined by body-body edges, within their part.
  std::vector<int32_t> island(static_cast<size_t>(N));
  std::iota(island.begin(), island.end(), 0);
  const auto root = [&](int32_t i) {  // iterative, with path halving: no recursion depth on large meshes
    while (island[size_t(i)] != i) i = island[size_t(i)] = island[size_t(island[size_t(i)])];
    return i;
  };
  for (Eigen::Index k = 0; k < edges.rows(); ++k) {
    const int32_t a = edges(k, 0), b = edges(k, 1);
    if (!m[a] && !m[b]) island[size_t(root(a))] = root(b);
  }
  std::vector<std::vector<int64_t>> members(static_cast<size_t>(count));
  for (int64_t i = 0; i < N; ++i) members[static_cast<size_t>(part[i])].push_back(i);
  for (std::vector<int64_t>& piece : members) {
    int64_t apparel = 0;
    std::map<int32_t, std::pair<int64_t, double>> islands;  // root -> (size, sum of p̂)
    for (const int64_t i : piece) {
      if (m[i]) {
        ++apparel;
      } else {
        auto& [size, sum] = islands[root(static_cast<int32_t>(i))];
        ++size, sum += q[i];
      }
    }
    if (2 * apparel < static_cast<int64_t>(piece.size())) continue;  // mostly body: a body part, left alone
    if (islands.empty()) {
      // Floating: its vertices of lowest p̂ hold it (ties by index, whatever the sort's implementation).
      const size_t held = std::min(piece.size(), static_cast<size_t>(std::ceil(share * double(piece.size()) - 1e-9)));
      std::partial_sort(piece.begin(), piece.begin() + static_cast<std::ptrdiff_t>(held), piece.end(),
                        [q](int64_t a, int64_t b) { return q[a] < q[b] || (q[a] == q[b] && a < b); });
      for (size_t j = 0; j < held; ++j) m[piece[j]] = false;
      if (hung) ++hung->pinned;
    } else if (islands.size() > 1) {
      // Held in several places: by the largest island (ties: the lower mean p̂, then the lower root); the others
      // would nail the piece to the body mid-way, so they are apparel.
      int32_t keep = -1;
      std::pair<int64_t, double> best{0, 0.0};
      for (const auto& [r, island_stats] : islands) {
        const auto& [size, sum] = island_stats;
        if (keep < 0 || size > best.first || (size == best.first && sum / size < best.second / best.first)) {
          keep = r, best = island_stats;
        }
      }
      for (const int64_t i : piece) {
        if (!m[i] && root(static_cast<int32_t>(i)) != keep) m[i] = true;
      }
      if (hung) hung->unnailed += static_cast<int>(islands.size()) - 1;
    }
  }
  return out;
}

BoundCharacter bind_character(const ModelBundle& bundle, const at::Tensor& V, const at::Tensor& F,
                              const at::Tensor& joints, const BindOptions& options) {
  AMT_CHECK(V.defined() && V.dim() == 2 && V.size(1) == 3 && V.size(0) > 0,
            "bind: V: expected (N, 3) rest positions with N > 0, found ",
            (V.defined() ? V.sizes() : at::IntArrayRef{}));
  AMT_CHECK(F.defined() && F.dim() == 2 && F.size(1) == 3, "bind: F: expected (F, 3) faces, found ",
            (F.defined() ? F.sizes() : at::IntArrayRef{}));
  AMT_CHECK(joints.defined() && joints.dim() == 2 && joints.size(1) == 3 && joints.size(0) == bundle.num_joints(),
            "bind: joints: expected (", bundle.num_joints(), ", 3) rest joints (the model's skeleton), found ",
            (joints.defined() ? joints.sizes() : at::IntArrayRef{}));
  const int64_t N = V.size(0), J = joints.size(0);
  if (F.size(0) > 0) {
    const int64_t lo = F.min().item<int64_t>(), hi = F.max().item<int64_t>();
    AMT_CHECK(lo >= 0 && hi < N, "bind: F: expected vertex indices in [0, ", N, "), found [", lo, ", ", hi, "]");
  }
  torch::NoGradGuard no_grad;
  BoundCharacter c;
  c.V = V.to(at::kFloat).contiguous();
  c.faces = F.to(at::kLong).contiguous();
  c.joints = joints.to(at::kFloat).contiguous();
  const MatrixX3f V_e = to_matrix3f(c.V), joints_e = to_matrix3f(c.joints);
  const MatrixX3i F_e = to_matrix3i(c.faces);
  c.edges = edge_tensor(unique_edges(F_e));

  // Segmentation (eq. 2) and the mask in use, on the linked topology: coincident copies are one point
  // (the segmenter sees them alike; a copy takes its weld group's value so that no seam straddles body and
  // apparel), and pieces that lie together hang together.
  const TopologyOptions topology_options;
  c.apparel_prob = apparel_probabilities(bundle, V_e, F_e, joints_e);
  std::vector<uint8_t> mask;
  if (options.apparel_mask.defined()) {
    AMT_CHECK(options.apparel_mask.dim() == 1 && options.apparel_mask.size(0) == N, "bind: apparel mask: expected ", N,
              " values (one per vertex), found ", options.apparel_mask.numel());
    mask = mask_vector(options.apparel_mask.to(at::kBool));
  } else {
    const std::vector<int32_t> weld = weld_vertices(V_e, topology_options.weld_tolerance);
    mask = weld_consistent_mask(mask_vector(c.apparel_prob.gt(0.5)), weld);
    const LinkedTopology before = linked_topology(V_e, F_e, mask, topology_options);
    mask = weld_consistent_mask(mask_vector(hang_apparel_pieces(mask_tensor(mask), c.apparel_prob, before.edges,
                                                                kFloatingPiecePinShare, &c.hung)),
                                weld);
  }
  const LinkedTopology topology = linked_topology(V_e, F_e, mask, topology_options);
  const std::vector<int32_t> canon = canonical_copies(topology.weld, mask);
  c.graph_edges = edge_tensor(topology.edges);
  c.topology_counts =
      at::tensor({int64_t(topology.seam_links), int64_t(topology.proximity_links), int64_t(topology.refused_links),
                  int64_t(topology.parts), int64_t(topology.welded_parts), int64_t(topology.linked_parts)},
                 at::kLong);
  c.apparel_mask = mask_tensor(mask);
  c.refiner_prob = c.apparel_mask.to(at::kFloat);
  c.apparel_ids = at::nonzero(c.apparel_mask).flatten().contiguous();
  c.body_ids = at::nonzero(c.apparel_mask.logical_not()).flatten().contiguous();
  c.body_edges = induced_edges(N, c.graph_edges, c.body_ids);
  c.apparel_edges = induced_edges(N, c.graph_edges, c.apparel_ids);
  c.apparel_neighbors = neighbor_table(c.apparel_ids.size(0), c.apparel_edges);
  const auto set_handles = [&] {
    if (!bundle.local_apparel() || bundle.apparel_dynamics->options.handle_spacing <= 0 || c.num_apparel() == 0) return;
    if (options.apparel_bones)
      AMT_CHECK(options.apparel_bones->indices.rows() == N, "bind: apparel bones: expected skin weights of ", N,
                " vertices, found ", options.apparel_bones->indices.rows());
    const ApparelRig rig = options.apparel_bones
                               ? bone_rig(c.V, c.apparel_ids, *options.apparel_bones)
                               : apparel_rig(c.V, c.graph_edges, c.apparel_ids, c.body_ids,
                                             handle_options(bundle.apparel_dynamics->options.handle_spacing));
    c.handle_rows = rig.rows;
    c.handle_vertex_handles = canonical_rows(rig.vertex_handles, c.apparel_ids, canon);
    c.handle_vertex_weights = canonical_rows(rig.vertex_weights, c.apparel_ids, canon);
    c.handle_edges = rig.edges;
  };
  set_handles();
  // The learned swing calibrated on the character's own physics (by the module that will move its apparel).
  const auto calibrate_swing = [&] {
    if (!options.calibrate_swing || !bundle.local_apparel() || !c.apparel_response.defined() || c.num_apparel() == 0)
      return;
    const double reference = bundle.apparel_dynamics_for(c.given_weights)->options.swing_reference;
    if (reference > 0) c.apparel_swing_gain = swing_calibration(c, reference).gain;
  };

  // Skinning weights (eq. 5-7) of the body, and optionally of every vertex.
  c.given_weights = options.weights.defined();
  if (options.weights.defined()) {
    AMT_CHECK(options.weights.dim() == 2 && options.weights.size(0) == N && options.weights.size(1) == J,
              "bind: weights: expected (", N, ", ", J, "), found ", options.weights.sizes());
    c.vertex_weights = options.weights.to(at::kFloat).contiguous();
    c.body_weights = c.vertex_weights.index_select(0, c.body_ids);
    c.apparel_anchor_weights = canonical_rows(apparel_anchor_weights_for(bundle.apparel_anchor(), c.V, c.graph_edges,
                                                                         c.apparel_ids, c.body_ids, c.body_weights),
                                              c.apparel_ids, canon);
    set_apparel_graph(c, options.physics_bones ? options.physics_bones.get() : options.apparel_bones.get());
    calibrate_swing();
    return c;
  }
  SkinningPredictor skinning = bundle.skinning_for(options.skinning_variant);
  if (c.body_ids.size(0) > 0) {
    c.G_body = welded_geodesics_tensor(V_e, F_e, joints_e, c.body_ids, canon, "bind: body");
    c.body_weights = skinning->forward(c.V.index_select(0, c.body_ids), c.joints, c.G_body).contiguous();
  } else {
    c.body_weights = at::zeros({0, J}, at::kFloat);
  }
  c.apparel_anchor_weights = canonical_rows(apparel_anchor_weights_for(bundle.apparel_anchor(), c.V, c.graph_edges,
                                                                       c.apparel_ids, c.body_ids, c.body_weights),
                                            c.apparel_ids, canon);
  set_apparel_graph(c, options.physics_bones ? options.physics_bones.get() : options.apparel_bones.get());
  if (options.all_vertex_weights) {
    // Apparel rows from f_s on the whole mesh; body rows stay those of the body part, so that "body
    // only" and "body + apparel" skin the body identically (Table 3).
    AMT_CHECK(F.size(0) > 0, "bind: faces: the skinning predictor needs faces, found none");
    std::vector<int32_t> weld_all = topology.weld;  // every vertex: welded whatever the mask
    const at::Tensor G_all =
        welded_geodesics_tensor(V_e, F_e, joints_e, at::arange(N, at::kLong), weld_all, "bind: mesh");
    c.vertex_weights = skinning->forward(c.V, c.joints, G_all).contiguous();
    if (c.body_ids.size(0) > 0) c.vertex_weights.index_copy_(0, c.body_ids, c.body_weights);
  }
  calibrate_swing();
  return c;
}

TopologyCounts BoundCharacter::topology() const {
  TopologyCounts t;
  if (!topology_counts.defined() || topology_counts.numel() != 6) return t;
  const at::Tensor n = topology_counts.to(at::kLong).contiguous();
  const int64_t* v = n.data_ptr<int64_t>();
  t.seam_links = v[0], t.proximity_links = v[1], t.refused_welds = v[2];
  t.parts = v[3], t.welded_parts = v[4], t.linked_parts = v[5];
  return t;
}

// === Starting a motion

at::Tensor rest_pose_transforms(const at::Tensor& rest_joints, int64_t frames) {
  const int64_t J = rest_joints.size(0);
  at::Tensor T = at::zeros({J, 3, 4}, at::kFloat);
  T.narrow(2, 0, 3).copy_(at::eye(3, at::kFloat).expand({J, 3, 3}));
  T.select(2, 3).copy_(rest_joints.to(at::kFloat));
  return T.unsqueeze(0).expand({frames, J, 3, 4}).contiguous();
}

at::Tensor rest_apparel_history(const BoundCharacter& character) {
  return character.V.index_select(0, character.apparel_ids).unsqueeze(0).expand({3, -1, -1}).contiguous();
}

at::Tensor motion_lead_in(const at::Tensor& first, const at::Tensor& rest_joints, int64_t frames) {
  AMT_CHECK(first.dim() == 3 && first.size(1) == 3 && first.size(2) == 4, "motion lead-in: first frame: expected ",
            "(J, 3, 4) joint transforms, found ", first.sizes());
  const int64_t J = first.size(0);
  AMT_CHECK(rest_joints.dim() == 2 && rest_joints.size(0) == J && rest_joints.size(1) == 3,
            "motion lead-in: rest joints: expected (", J, ", 3), found ", rest_joints.sizes());
  AMT_CHECK(frames >= 0, "motion lead-in: frames: expected >= 0, found ", frames);
  const at::Tensor T0 = first.to(at::kFloat).contiguous(), J0 = rest_joints.to(at::kFloat).contiguous();
  at::Tensor out = at::empty({frames, J, 3, 4}, at::kFloat);
  const float* t0 = T0.data_ptr<float>();
  const float* j0 = J0.data_ptr<float>();
  float* dst = out.data_ptr<float>();
  for (int64_t j = 0; j < J; ++j) {
    const Eigen::Map<const Eigen::Matrix<float, 3, 4, Eigen::RowMajor>> M(t0 + 12 * j);
    Eigen::Matrix3f R = M.leftCols<3>();
    const Eigen::Quaternionf q = Eigen::Quaternionf(R).normalized();
    const Eigen::Vector3f rest(j0[3 * j], j0[3 * j + 1], j0[3 * j + 2]);
    const Eigen::Vector3f target = M.col(3);
    for (int64_t k = 0; k < frames; ++k) {
      const float s = lead_in_weight(k, frames);
      Eigen::Map<Eigen::Matrix<float, 3, 4, Eigen::RowMajor>> D(dst + 12 * (k * J + j));
      D.leftCols<3>() = Eigen::Quaternionf::Identity().slerp(s, q).toRotationMatrix();
      D.col(3) = (1.0f - s) * rest + s * target;
    }
  }
  return out;
}

// === Stepping

const char* pipeline_stages_name(PipelineStages stages) {
  switch (stages) {
    case PipelineStages::kBodyOnly:
      return "body_only";
    case PipelineStages::kBodyApparel:
      return "body_apparel";
    case PipelineStages::kFull:
      return "full";
  }
  return "?";
}

PipelineStepper::PipelineStepper(const ModelBundle& bundle, const BoundCharacter& character, const at::Tensor& history,
                                 PipelineStages stages, ApparelSource source, double inertia)
    : bundle_(bundle), character_(character), stages_(stages), source_(source), inertia_(inertia) {
  if (stages_ == PipelineStages::kBodyOnly) {
    AMT_CHECK(character_.vertex_weights.defined(), "pipeline: body only needs weights of every vertex (bind with ",
              "BindOptions::all_vertex_weights or BindOptions::weights)");
    lbs_rest_ = character_.V;
    lbs_weights_ = character_.vertex_weights;
  } else {
    lbs_rest_ = character_.V.index_select(0, character_.body_ids);
    lbs_weights_ = character_.body_weights;
    const bool anchored =
        source_ != ApparelSource::kNetwork || bundle_.local_apparel() || bundle_.apparel->options.skinned_anchor;
    if (anchored && character_.num_apparel() > 0) {
      // One LBS call skins the body (B̂) and the apparel's anchor S^(t): rows N_b.. are S.
      lbs_rest_ = at::cat({lbs_rest_, character_.V.index_select(0, character_.apparel_ids)}, 0);
      lbs_weights_ = at::cat({lbs_weights_, character_.apparel_anchor_weights}, 0);
    }
  }
  if (stages_ == PipelineStages::kFull) {
    c10::InferenceMode inference;
    refiner_character_ = bundle_.refiner.ptr()->prepare(character_.V, character_.refiner_prob);
  }
  if (source_ == ApparelSource::kNetwork && bundle_.local_apparel() && character_.handle_rows.defined()) {
    c10::InferenceMode inference;
    rig_ = character_.rig();
    handle_graph_ = handle_graph(character_.apparel_graph(), rig_);
  }
  if (source_ == ApparelSource::kNetwork && bundle_.local_apparel() && stages_ != PipelineStages::kBodyOnly &&
      character_.apparel_swing_gain.defined() && character_.num_apparel() > 0) {
    const at::Tensor& gain = character_.apparel_swing_gain;
    AMT_CHECK(gain.dim() == 1 && gain.size(0) == character_.num_apparel(), "pipeline: swing gain: expected (",
              character_.num_apparel(), "), found ", gain.sizes());
    // A gain below 1 scales what the stepper shows (below); every gain 1 is the module's output exactly, not
    // S + 1 (Â - S) rounded. A gain above 1 scales the handles' offsets before the vertices follow them turning, and
    // the stretch limit applies after it, so a livened piece swings further as a piece. A module that moves vertices
    // is not livened: its offsets scaled up would stretch the piece past the limit the stepper keeps.
    const at::Tensor g = gain.to(at::kFloat);
    if (g.lt(1.0f).any().item<bool>()) swing_gain_ = g.clamp_max(1.0f).unsqueeze(1).contiguous();
    if (rig_.defined() && g.gt(1.0f).any().item<bool>())
      handle_gain_ = g.clamp_min(1.0f).index_select(0, rig_.rows).unsqueeze(1).contiguous();
  }
  set_strain_limit(kDefaultStrainLimit);
  reset(history);
}

void PipelineStepper::set_strain_limit(float max_stretch, int iterations, float min_stretch) {
  strain_ = StrainLimiter();
  const int64_t N_a = character_.num_apparel(), N_b = character_.num_body();
  if (max_stretch == 0.0f || source_ != ApparelSource::kNetwork || !bundle_.local_apparel() ||
      stages_ == PipelineStages::kBodyOnly || N_a == 0 || !character_.graph_edges.defined() ||
      !character_.edges.defined())
    return;
  // Each vertex's place in the limiter's numbering: apparel first, then body.
  std::vector<int32_t> place(size_t(character_.num_vertices()), -1);
  const at::Tensor apparel = character_.apparel_ids.to(at::kLong).contiguous();
  const at::Tensor body = character_.body_ids.to(at::kLong).contiguous();
  for (int64_t k = 0; k < N_a; ++k) place[size_t(apparel.data_ptr<int64_t>()[k])] = int32_t(k);
  for (int64_t k = 0; k < N_b; ++k) place[size_t(body.data_ptr<int64_t>()[k])] = int32_t(N_a + k);
  const at::Tensor E = character_.graph_edges.to(at::kLong).contiguous();
  const at::Tensor V = character_.V.to(at::kFloat).contiguous();
  const int64_t* e = E.data_ptr<int64_t>();
  const float* v = V.data_ptr<float>();
  // The mesh's own edges and its seam links, not the proximity links between pieces: those join the two sides of
  // a double-sided strip a millimetre or two apart, and bounding them too moves vertices against the mesh edges
  // around them (measured on the artist-style remakes: tearing 0.71 % with them, 0.52 % without; up to 11
  // projections per frame with them, 4 without).
  std::vector<std::pair<int64_t, int64_t>> mesh_edges;
  {
    const at::Tensor M = character_.edges.to(at::kLong).contiguous();
    const int64_t* m = M.data_ptr<int64_t>();
    for (int64_t k = 0; k < M.size(0); ++k)
      mesh_edges.emplace_back(std::min(m[2 * k], m[2 * k + 1]), std::max(m[2 * k], m[2 * k + 1]));
    std::sort(mesh_edges.begin(), mesh_edges.end());
  }
  const auto is_mesh_edge = [&](int64_t a, int64_t b) {
    return std::binary_search(mesh_edges.begin(), mesh_edges.end(), std::make_pair(std::min(a, b), std::max(a, b)));
  };
  // Vertices of one weld group are one point (rest length 0: the limiter welds them), whatever their distance: a
  // group chains vertices each within the tolerance of the next, so a seam link can be longer than the tolerance.
  const float weld = TopologyOptions().weld_tolerance;
  const std::vector<int32_t> group = weld_vertices(to_matrix3f(V), weld);
  std::vector<std::array<int32_t, 2>> kept;
  std::vector<float> rest;
  for (int64_t k = 0; k < E.size(0); ++k) {
    const int64_t a = e[2 * k], b = e[2 * k + 1];
    const int32_t pa = place[size_t(a)], pb = place[size_t(b)];
    if (pa < 0 || pb < 0 || (pa >= N_a && pb >= N_a)) continue;
    const bool seam = group[size_t(a)] == group[size_t(b)];
    if (!seam && !is_mesh_edge(a, b)) continue;  // a proximity link
    const float dx = v[3 * a] - v[3 * b], dy = v[3 * a + 1] - v[3 * b + 1], dz = v[3 * a + 2] - v[3 * b + 2];
    kept.push_back({pa, pb});
    rest.push_back(seam ? 0.0f : std::sqrt(dx * dx + dy * dy + dz * dz));
  }
  MatrixX2i edges(Eigen::Index(kept.size()), 2);
  for (size_t k = 0; k < kept.size(); ++k) edges.row(Eigen::Index(k)) << kept[k][0], kept[k][1];
  strain_ = StrainLimiter(edges, rest, int(N_a), int(N_b), max_stretch, iterations, weld, min_stretch);
}

void PipelineStepper::reset(const at::Tensor& history, const at::Tensor& history_transforms) {
  const int64_t N_a = character_.num_apparel(), J = character_.joints.size(0);
  AMT_CHECK(
      history.defined() && history.dim() == 3 && history.size(0) == 3 && history.size(1) == N_a && history.size(2) == 3,
      "pipeline: apparel history: expected (3, ", N_a, ", 3), found ",
      (history.defined() ? history.sizes() : at::IntArrayRef{}));
  history_ = history.to(at::kFloat).contiguous();
  frames_ = 0;
  if (source_ == ApparelSource::kNetwork && !bundle_.local_apparel()) return;
  c10::InferenceMode inference;
  if (history_transforms.defined()) {
    AMT_CHECK(history_transforms.dim() == 4 && history_transforms.size(0) == 3 && history_transforms.size(1) == J &&
                  history_transforms.size(2) == 3 && history_transforms.size(3) == 4,
              "pipeline: history transforms: expected (3, ", J, ", 3, 4), found ", history_transforms.sizes());
    history_transforms_ = history_transforms.to(at::kFloat).contiguous();
  } else {
    history_transforms_ = rest_pose_transforms(character_.joints, 3);
  }
  const at::Tensor A_rest = character_.V.index_select(0, character_.apparel_ids);
  history_anchors_ =
      N_a > 0 ? linear_blend_skinning(A_rest, character_.apparel_anchor_weights, history_transforms_, character_.joints)
              : at::zeros({3, 0, 3}, at::kFloat);
  if (rig_.defined()) {
    // The module's own states are the handles': the history's rows at the handles.
    handle_history_ = history_.index_select(1, rig_.rows).contiguous();
    handle_history_anchors_ = history_anchors_.index_select(1, rig_.rows).contiguous();
  }
}

StepOutput PipelineStepper::step_detailed(const at::Tensor& joint_transforms, StepTimes* times) {
  using Clock = std::chrono::steady_clock;
  const auto seconds = [](Clock::time_point a, Clock::time_point b) {
    return std::chrono::duration<double>(b - a).count();
  };
  const int64_t J = character_.joints.size(0);
  AMT_CHECK(joint_transforms.dim() == 3 && joint_transforms.size(0) == J && joint_transforms.size(1) == 3 &&
                joint_transforms.size(2) == 4,
            "pipeline: joint transforms: expected (", J, ", 3, 4), found ", joint_transforms.sizes());
  c10::InferenceMode inference;
  const auto t0 = Clock::now();
  const at::Tensor T = joint_transforms.to(at::kFloat).unsqueeze(0);  // (1, J, 3, 4)
  StepOutput out;
  const at::Tensor skinned = lbs_rest_.size(0) > 0
                                 ? linear_blend_skinning(lbs_rest_, lbs_weights_, T, character_.joints).squeeze(0)
                                 : at::zeros({0, 3}, at::kFloat);  // eq. (4)
  ++frames_;
  const auto t1 = Clock::now();
  if (stages_ == PipelineStages::kBodyOnly) {
    out.V_hat = skinned;
    if (times) *times = StepTimes{seconds(t0, t1), 0.0, 0.0};
    return out;
  }
  const int64_t N_b = character_.num_body();
  out.B_hat = skinned.narrow(0, 0, N_b);
  if (character_.num_apparel() > 0) {
    const at::Tensor anchor = skinned.size(0) > N_b ? skinned.narrow(0, N_b, skinned.size(0) - N_b) : at::Tensor();
    if (source_ == ApparelSource::kNetwork && !bundle_.local_apparel()) {
      out.A_hat =
          bundle_.apparel.ptr()->step(history_, T.squeeze(0), character_.apparel_neighbors, anchor);  // eq. (11)
    } else {
      // Frames t-3..t of the motion and the anchors, for the detail vectors.
      const at::Tensor window_T = at::cat({history_transforms_, T}, 0).unsqueeze(0);                 // (1, 4, J, 3, 4)
      const at::Tensor window_S = at::cat({history_anchors_, anchor.unsqueeze(0)}, 0).unsqueeze(0);  // (1, 4, N_a, 3)
      const at::Tensor h = history_.unsqueeze(0);
      if (source_ == ApparelSource::kNetwork && rig_.defined()) {
        // The module moves the handles; every vertex follows its handles, turning as they turn.
        const at::Tensor S_h = anchor.index_select(0, rig_.rows);
        const at::Tensor window_S_h = at::cat({handle_history_anchors_, S_h.unsqueeze(0)}, 0).unsqueeze(0);
        const at::Tensor A_h = bundle_.apparel_dynamics_for(character_.given_weights)
                                   .ptr()
                                   ->step(handle_history_.unsqueeze(0), window_T, window_S_h, handle_graph_)
                                   .squeeze(0);
        // What the handles show swings by the calibrated gain (swing_calibration); the module keeps its own A_h.
        const at::Tensor shown = handle_gain_.defined() ? S_h + handle_gain_ * (A_h - S_h) : A_h;
        out.A_hat = turning_handles_ ? follow_turning_handles(shown, S_h, anchor, rig_)
                                     : follow_handles(shown, S_h, anchor, rig_);
        handle_history_ = at::cat({handle_history_.narrow(0, 1, 2), A_h.unsqueeze(0)}, 0);
        out.A_handles = A_h;
        handle_history_anchors_ = window_S_h.squeeze(0).narrow(0, 1, 3);
      } else if (source_ == ApparelSource::kNetwork) {
        out.A_hat = bundle_.apparel_dynamics_for(character_.given_weights)
                        .ptr()
                        ->step(h, window_T, window_S, character_.apparel_graph())
                        .squeeze(0);
      } else {
        const double inertia = source_ == ApparelSource::kInertial ? inertia_ : 0.0;
        out.A_hat = detail_rule_step(h, window_T, window_S, character_.apparel_frame_joints, inertia).squeeze(0);
      }
      history_transforms_ = window_T.squeeze(0).narrow(0, 1, 3);
      history_anchors_ = window_S.squeeze(0).narrow(0, 1, 3);
    }
    if (!strain_.empty()) {
      out.A_hat = out.A_hat.to(at::kFloat).contiguous().clone();
      const at::Tensor fixed = out.B_hat.to(at::kFloat).contiguous();
      strain_.apply(out.A_hat.data_ptr<float>(), fixed.data_ptr<float>());
    }
    history_ = at::cat({history_.narrow(0, 1, 2), out.A_hat.unsqueeze(0)}, 0);
    // The module keeps its own state; what it shows swings by the calibrated gain (swing_calibration).
    if (swing_gain_.defined()) out.A_hat = anchor + swing_gain_ * (out.A_hat - anchor);
  } else {
    out.A_hat = at::zeros({0, 3}, at::kFloat);
  }
  const auto t2 = Clock::now();
  // tile(Â, B̂) (eq. 16) by the bound index lists, which partition the mesh (as tile_apparel_body does by the mask).
  at::Tensor tiled = at::empty({character_.num_vertices(), 3}, at::kFloat);
  tiled.index_copy_(0, character_.apparel_ids, out.A_hat).index_copy_(0, character_.body_ids, out.B_hat);
  out.V_hat = stages_ == PipelineStages::kFull
                  ? bundle_.refiner.ptr()->forward(tiled, refiner_character_).V_hat  // eq. (16)
                  : tiled;
  if (times) *times = StepTimes{seconds(t0, t1), seconds(t1, t2), seconds(t2, Clock::now())};
  return out;
}

at::Tensor PipelineStepper::step(const at::Tensor& joint_transforms, StepTimes* times) {
  return step_detailed(joint_transforms, times).V_hat;
}

// === Calibrating the swing

SwingCalibration apparel_piece_swing(const at::Tensor& response, const at::Tensor& apparel_edges) {
  AMT_CHECK(response.defined() && response.dim() == 2 && response.size(1) == kApparelResponseChannels,
            "swing calibration: response: expected (N_a, ", kApparelResponseChannels, "), found ",
            (response.defined() ? response.sizes() : at::IntArrayRef{}));
  const int N_a = int(response.size(0));
  AMT_CHECK(apparel_edges.defined() && apparel_edges.dim() == 2 && apparel_edges.size(1) == 2,
            "swing calibration: apparel edges: expected (E_a, 2)");
  AMT_CHECK(apparel_edges.numel() == 0 ||
                (apparel_edges.min().item<int64_t>() >= 0 && apparel_edges.max().item<int64_t>() < N_a),
            "swing calibration: apparel edges: expected indices in [0, ", N_a, ")");
  // Pieces: connected parts of the apparel over the edges.
  const at::Tensor E = apparel_edges.to(at::kInt).contiguous();
  int P = 0;
  const std::vector<int32_t> piece =
      connected_components(N_a, Eigen::Map<const MatrixX2i>(E.data_ptr<int32_t>(), E.size(0), 2), &P);
  std::vector<double> swing(size_t(P), 0.0);
  std::vector<int64_t> count(size_t(P), 0);
  const at::Tensor r = response.to(at::kFloat).contiguous();
  const float* rv = r.data_ptr<float>();
  for (int v = 0; v < N_a; ++v) {
    const float* row = rv + int64_t(v) * kApparelResponseChannels;
    swing[size_t(piece[size_t(v)])] += double(row[0]) * (double(row[1]) + double(row[2]));
    ++count[size_t(piece[size_t(v)])];
  }
  SwingCalibration out;
  out.piece_of = at::tensor(std::vector<int64_t>(piece.begin(), piece.end()), at::kLong);
  out.piece_vertices = at::tensor(count, at::kLong);
  out.piece_swing = at::empty({P}, at::kFloat);
  for (int p = 0; p < P; ++p) out.piece_swing[p] = float(swing[size_t(p)] / double(count[size_t(p)]));
  return out;
}

SwingCalibration swing_calibration(const BoundCharacter& character, double swing_reference) {
  AMT_CHECK(character.apparel_response.defined() && character.apparel_response.size(0) == character.num_apparel(),
            "swing calibration: the character's physics response is unknown");
  AMT_CHECK(std::isfinite(swing_reference) && swing_reference > 0, "swing calibration: reference: expected > 0, found ",
            swing_reference);
  SwingCalibration out = apparel_piece_swing(character.apparel_response, character.apparel_edges);
  out.piece_gain = (out.piece_swing / swing_reference).clamp(0.0, 1.0);
  out.gain = out.piece_gain.index_select(0, out.piece_of);
  return out;
}

double swing_reference(const std::vector<SwingCalibration>& characters) {
  double least = 0.0;
  bool any = false;
  for (const SwingCalibration& c : characters) {
    if (!c.piece_swing.defined() || c.piece_swing.numel() == 0) continue;
    const double m = c.piece_swing.min().item<double>();
    least = any ? std::min(least, m) : m;
    any = true;
  }
  return least;
}

SwingCalibration fit_swing_calibration(const at::Tensor& A_hat, const at::Tensor& S, const at::Tensor& G,
                                       const at::Tensor& apparel_edges) {
  AMT_CHECK(A_hat.defined() && A_hat.dim() == 3 && A_hat.size(2) == 3, "swing calibration: module apparel: expected ",
            "(T, N_a, 3), found ", (A_hat.defined() ? A_hat.sizes() : at::IntArrayRef{}));
  AMT_CHECK(S.defined() && S.sizes() == A_hat.sizes() && G.defined() && G.sizes() == A_hat.sizes(),
            "swing calibration: anchor skinning and simulation: expected ", A_hat.sizes(), " as the module's apparel");
  const int64_t N_a = A_hat.size(1);
  AMT_CHECK(apparel_edges.defined() && apparel_edges.dim() == 2 && apparel_edges.size(1) == 2,
            "swing calibration: apparel edges: expected (E_a, 2)");
  AMT_CHECK(apparel_edges.numel() == 0 ||
                (apparel_edges.min().item<int64_t>() >= 0 && apparel_edges.max().item<int64_t>() < N_a),
            "swing calibration: apparel edges: expected indices in [0, ", N_a, ")");
  const at::Tensor d = (A_hat - S).to(at::kDouble), g = (G - S).to(at::kDouble);
  AMT_CHECK(d.isfinite().all().item<bool>() && g.isfinite().all().item<bool>(),
            "swing calibration: expected finite positions");
  const at::Tensor E = apparel_edges.to(at::kInt).contiguous();
  int P = 0;
  const std::vector<int32_t> piece =
      connected_components(int(N_a), Eigen::Map<const MatrixX2i>(E.data_ptr<int32_t>(), E.size(0), 2), &P);
  SwingCalibration out;
  out.piece_of = at::tensor(std::vector<int64_t>(piece.begin(), piece.end()), at::kLong);
  // Per vertex over the frames, then per piece.
  const at::Tensor along = (d * g).sum(at::IntArrayRef{0, 2}), own = (d * d).sum(at::IntArrayRef{0, 2});
  const at::Tensor num = at::zeros({P}, at::kDouble).index_add_(0, out.piece_of, along);
  const at::Tensor den = at::zeros({P}, at::kDouble).index_add_(0, out.piece_of, own);
  out.piece_vertices = at::zeros({P}, at::kLong).index_add_(0, out.piece_of, at::ones({N_a}, at::kLong));
  // A piece the module leaves on its anchor (|Â - S| below a micrometre per vertex and frame) has nothing to scale.
  const at::Tensor moved = den.gt(1e-12 * double(A_hat.size(0)) * out.piece_vertices.to(at::kDouble));
  const at::Tensor scale =
      at::where(moved, num / den.clamp_min(1e-30), at::ones({P}, at::kDouble)).clamp(0.0, kMaxSwingGain);
  // The module loses to rigid skinning on the piece (|Â - G|^2 > |S - G|^2) exactly when the scale is below 1/2: taken
  // as fitted there; kept at 1 from 3/4 to 1, where the module clearly wins (on lively rigs the scale fitted on one
  // motion falls below 1 with the module's phase, and 1 measured better on other motions); linear between.
  // Above 1 the module swings in step with the rig but less far: livened by the scale (at most kMaxSwingGain).
  out.piece_gain = at::where(scale.le(0.5), scale, at::where(scale.le(1.0), (2.0 * scale - 0.5).clamp_max(1.0), scale))
                       .to(at::kFloat);
  out.gain = out.piece_gain.index_select(0, out.piece_of);
  return out;
}

namespace {

// What fit_swing_on_motions pools from one motion: the module's apparel, its anchor skinning and the truth on the
// frames the module predicts, each (F, N_a, 3).
struct SwingFrames {
  at::Tensor A_hat, S, G;
};

SwingFrames swing_frames(const ModelBundle& bundle, const BoundCharacter& plain, const SwingCalibrationMotion& run,
                         float strain_limit, int64_t window) {
  constexpr int64_t kHistoryFrames = 3;
  const at::Tensor &lead_in = run.lead_in, &motion = run.motion, &truth = run.truth;
  const int64_t T = motion.defined() && motion.dim() == 4 ? motion.size(0) : -1, N_a = plain.num_apparel();
  AMT_CHECK(motion.defined() && lead_in.defined() && motion.dim() == 4 && lead_in.dim() == 4 && T > 0,
            "swing calibration: motion and lead-in: expected (T, J, 3, 4) with T > 0, found ",
            (motion.defined() ? motion.sizes() : at::IntArrayRef{}), " and ",
            (lead_in.defined() ? lead_in.sizes() : at::IntArrayRef{}));
  AMT_CHECK(truth.defined() && truth.dim() == 3 && truth.size(0) == T && truth.size(1) == N_a && truth.size(2) == 3,
            "swing calibration: the simulation's apparel: expected (", T, ", ", N_a, ", 3), found ",
            (truth.defined() ? truth.sizes() : at::IntArrayRef{}));
  AMT_CHECK(window == 0 || (window > kHistoryFrames && window <= T), "swing calibration: window: expected 0 or ",
            kHistoryFrames + 1, "..", T, " frames (the motion's length), found ", window);
  const at::Tensor G_all = truth.to(at::kFloat);
  PipelineStepper stepper(bundle, plain, rest_apparel_history(plain), PipelineStages::kBodyApparel);
  stepper.set_strain_limit(strain_limit);
  // The frames the module predicts: all after the lead-in, or each window's after its history (the windows' predicted
  // frames follow on from each other: window_start marks where the stepper restarts from the truth).
  std::vector<int64_t> frames;
  std::vector<uint8_t> window_start;
  if (window == 0) {
    for (int64_t k = 0; k < lead_in.size(0); ++k) stepper.step(lead_in[k]);
    for (int64_t t = 0; t < T; ++t) frames.push_back(t), window_start.push_back(0);
  } else {
    for (int64_t s = 0; s + window <= T; s += window - kHistoryFrames)
      for (int64_t t = s + kHistoryFrames; t < s + window; ++t)
        frames.push_back(t), window_start.push_back(t == s + kHistoryFrames);
  }
  const int64_t F = static_cast<int64_t>(frames.size());
  const at::Tensor A_rest = plain.V.index_select(0, plain.apparel_ids);
  // Frame by frame: linear_blend_skinning's memory is O(T N 12) over a whole motion.
  SwingFrames out{at::empty({F, N_a, 3}, at::kFloat), at::empty({F, N_a, 3}, at::kFloat),
                  at::empty({F, N_a, 3}, at::kFloat)};
  for (int64_t k = 0; k < F; ++k) {
    const int64_t t = frames[size_t(k)];
    if (window_start[size_t(k)])
      stepper.reset(G_all.narrow(0, t - kHistoryFrames, kHistoryFrames),
                    motion.narrow(0, t - kHistoryFrames, kHistoryFrames));
    out.A_hat[k] = stepper.step_detailed(motion[t]).A_hat;
    out.S[k] = linear_blend_skinning(A_rest, plain.apparel_anchor_weights, motion[t].unsqueeze(0), plain.joints)[0];
    out.G[k] = G_all[t];
  }
  return out;
}

}  // namespace

SwingCalibration fit_swing_on_motions(const ModelBundle& bundle, const BoundCharacter& character,
                                      const std::vector<SwingCalibrationMotion>& motions, float strain_limit,
                                      int64_t window) {
  AMT_CHECK(!motions.empty(), "swing calibration: expected at least one motion, found none");
  c10::InferenceMode inference;
  BoundCharacter plain = character;
  plain.apparel_swing_gain = at::Tensor();
  std::vector<at::Tensor> A_hat, S, G;
  for (const SwingCalibrationMotion& run : motions) {
    SwingFrames f = swing_frames(bundle, plain, run, strain_limit, window);
    A_hat.push_back(f.A_hat), S.push_back(f.S), G.push_back(f.G);
  }
  return fit_swing_calibration(at::cat(A_hat, 0), at::cat(S, 0), at::cat(G, 0), plain.apparel_edges);
}

SwingCalibration fit_swing_on_motion(const ModelBundle& bundle, const BoundCharacter& character,
                                     const at::Tensor& lead_in, const at::Tensor& motion, const at::Tensor& truth,
                                     float strain_limit, int64_t window) {
  return fit_swing_on_motions(bundle, character, {{lead_in, motion, truth}}, strain_limit, window);
}

at::Tensor run_pipeline(const ModelBundle& bundle, const BoundCharacter& character, const at::Tensor& history,
                        const at::Tensor& joint_transforms, PipelineStages stages) {
  AMT_CHECK(joint_transforms.dim() == 4, "pipeline: joint transforms: expected (T, J, 3, 4), found ",
            joint_transforms.sizes());
  PipelineStepper stepper(bundle, character, history, stages);
  const int64_t T = joint_transforms.size(0);
  std::vector<at::Tensor> frames;
  frames.reserve(T);
  for (int64_t t = 0; t < T; ++t) frames.push_back(stepper.step(joint_transforms[t]));
  c10::InferenceMode inference;
  if (frames.empty()) return at::zeros({0, character.num_vertices(), 3}, at::kFloat);
  return at::stack(frames, 0);
}

}  // namespace amt
