#include "data_tools/builder/segmenter_augmentation.h"

#include <algorithm>

#include "data_tools/geometry/error.h"

namespace amt {
namespace {

// The labels of the connected parts over F's edges and the largest one.
std::vector<int32_t> parts_of(const TriMesh& mesh, int32_t& largest) {
  int count = 0;
  const std::vector<int32_t> label = connected_components(mesh.num_vertices(), unique_edges(mesh.F), &count);
  std::vector<int32_t> size(static_cast<size_t>(count), 0);
  for (const int32_t l : label) ++size[static_cast<size_t>(l)];
  largest = static_cast<int32_t>(std::max_element(size.begin(), size.end()) - size.begin());
  return label;
}

// The example restricted to `ids` (ascending): submesh, weights and mask rows, skeleton kept.
SegmenterExample restricted(const SegmenterExample& e, const std::vector<int32_t>& ids, bool zero_mask) {
  SegmenterExample out;
  out.mesh = submesh(e.mesh.V, e.mesh.F, ids);
  out.skeleton = e.skeleton;
  out.body_weights.resize(static_cast<Eigen::Index>(ids.size()), e.body_weights.cols());
  out.apparel_mask.resize(ids.size());
  for (size_t k = 0; k < ids.size(); ++k) {
    if (e.body_weights.cols() > 0) out.body_weights.row(Eigen::Index(k)) = e.body_weights.row(ids[k]);
    out.apparel_mask[k] = zero_mask ? 0 : e.apparel_mask[size_t(ids[k])];
  }
  return out;
}

}  // namespace

std::string mirrored_joint_name(const std::string& name) {
  if (name.rfind("left_", 0) == 0) return "right_" + name.substr(5);
  if (name.rfind("right_", 0) == 0) return "left_" + name.substr(6);
  return name;
}

SegmenterExample mirrored_example(const SegmenterExample& e) {
  const int J = e.skeleton.num_joints();
  std::vector<int> mirror(static_cast<size_t>(J), -1);
  for (int j = 0; j < J; ++j) {
    const std::string m = mirrored_joint_name(e.skeleton.names[size_t(j)]);
    mirror[size_t(j)] = e.skeleton.index_of(m);
    AMT_CHECK(mirror[size_t(j)] >= 0, "mirrored example: joint ", e.skeleton.names[size_t(j)],
              ": expected its mirror joint ", m, " in the skeleton, found none");
  }
  SegmenterExample out = e;
  out.mesh.V.col(0) = -e.mesh.V.col(0);
  out.mesh.F.col(1) = e.mesh.F.col(2);
  out.mesh.F.col(2) = e.mesh.F.col(1);
  for (int j = 0; j < J; ++j) {
    out.skeleton.rest_joints.row(j) = e.skeleton.rest_joints.row(mirror[size_t(j)]);
    out.skeleton.rest_joints(j, 0) = -out.skeleton.rest_joints(j, 0);
    if (e.body_weights.cols() == J) out.body_weights.col(j) = e.body_weights.col(mirror[size_t(j)]);
  }
  return out;
}

SegmenterExample bare_body_example(const SegmenterExample& e) {
  int32_t largest = 0;
  const std::vector<int32_t> label = parts_of(e.mesh, largest);
  std::vector<int32_t> ids;
  for (int32_t i = 0; i < e.mesh.num_vertices(); ++i)
    if (label[size_t(i)] == largest && e.apparel_mask[size_t(i)] == 0) ids.push_back(i);
  return restricted(e, ids, /*zero_mask=*/true);
}

bool builder_layout(const SegmenterExample& e) {
  const auto& names = canonical_joint_names();
  if (e.mesh.num_vertices() == 0 || e.skeleton.names != std::vector<std::string>(names.begin(), names.end()))
    return false;
  int32_t largest = 0;
  return parts_of(e.mesh, largest)[0] == largest;
}

SegmenterExample open_parts_example(const SegmenterExample& e, bool bare, const OpenPartsOptions& options) {
  const auto& names = canonical_joint_names();
  AMT_CHECK(e.skeleton.names == std::vector<std::string>(names.begin(), names.end()),
            "open parts example: expected the canonical skeleton's ", names.size(), " joints, found ",
            e.skeleton.num_joints());
  int32_t largest = 0;
  const std::vector<int32_t> label = parts_of(e.mesh, largest);
  int Nb = 0;
  while (Nb < e.mesh.num_vertices() && label[size_t(Nb)] == largest) ++Nb;
  AMT_CHECK(Nb > 0, "open parts example: expected the body's vertices first, found vertex 0 off the largest part");
  DressedCharacter dressed;
  dressed.mesh = e.mesh;
  dressed.body_weights = e.body_weights;
  dressed.apparel_mask = e.apparel_mask;
  dressed.body.mesh.V = e.mesh.V.topRows(Nb);
  const OpenPartsCharacter open = open_parts_character(dressed, options);
  SegmenterExample out;
  out.mesh = open.mesh;
  out.skeleton = e.skeleton;
  out.body_weights = open.body_weights;
  out.apparel_mask = open.apparel_mask;
  if (!bare) return out;
  std::vector<int32_t> ids;
  for (int32_t i = 0; i < out.mesh.num_vertices(); ++i)
    if (open.part[size_t(i)] >= 0) ids.push_back(i);
  return restricted(out, ids, /*zero_mask=*/true);
}

}  // namespace amt
