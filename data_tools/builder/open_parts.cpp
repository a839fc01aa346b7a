#include "data_tools/builder/open_parts.h"

#include <algorithm>
#include <cmath>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/shapes.h"
#include "data_tools/geometry/skeleton.h"
#include "data_tools/geometry/winding_number.h"

namespace amt {

OpenPartsCharacter open_parts_character(const DressedCharacter& dressed, const OpenPartsOptions& options) {
  AMT_CHECK(options.hole_distance >= 0 && std::isfinite(options.hole_distance),
            "open parts: hole distance: expected >= 0 metres, found ", options.hole_distance);
  AMT_CHECK(options.overlap_inset >= 0 && std::isfinite(options.overlap_inset),
            "open parts: overlap inset: expected >= 0 metres, found ", options.overlap_inset);
  AMT_CHECK(options.cap_scale > 0 && std::isfinite(options.cap_scale), "open parts: cap scale: expected > 0, found ",
            options.cap_scale);
  const TriMesh& in = dressed.mesh;
  const MatrixXfR& W = dressed.body_weights;
  const int N = in.num_vertices(), Nb = dressed.body.mesh.num_vertices(), J = int(W.cols());
  const auto& names = canonical_joint_names();
  const int head = int(std::find(names.begin(), names.end(), "head") - names.begin());
  AMT_CHECK(J == int(names.size()), "open parts: expected ", names.size(), " body weight columns, found ", J);

  // Body faces (three corners on the generated body) and the dominant joint of each.
  std::vector<int32_t> body_faces, other_faces;
  for (int f = 0; f < in.num_faces(); ++f) {
    const bool body = in.F(f, 0) < Nb && in.F(f, 1) < Nb && in.F(f, 2) < Nb;
    (body ? body_faces : other_faces).push_back(f);
  }
  std::vector<int32_t> face_joint(size_t(in.num_faces()), -1);
  for (const int32_t f : body_faces) {
    Eigen::RowVectorXf sum = W.row(in.F(f, 0)) + W.row(in.F(f, 1)) + W.row(in.F(f, 2));
    sum.maxCoeff(&face_joint[size_t(f)]);
  }
  // Holes: body faces near the clothes at rest.
  std::vector<uint8_t> dropped(size_t(in.num_faces()), 0);
  OpenPartsCharacter out;
  if (options.hole_distance > 0 && !other_faces.empty()) {
    MatrixX3i clothes(Eigen::Index(other_faces.size()), 3);
    for (size_t k = 0; k < other_faces.size(); ++k) clothes.row(Eigen::Index(k)) = in.F.row(other_faces[k]);
    const WindingNumberTree tree(in.V, clothes);
    for (const int32_t f : body_faces) {
      const Eigen::Vector3f centroid = (in.V.row(in.F(f, 0)) + in.V.row(in.F(f, 1)) + in.V.row(in.F(f, 2))).transpose() / 3.0f;
      if (tree.distance(centroid) < options.hole_distance) dropped[size_t(f)] = 1, ++out.dropped_faces;
    }
  }
  // Vertex -> incident body faces, for the seam rings.
  std::vector<std::vector<int32_t>> incident(static_cast<size_t>(Nb));
  for (const int32_t f : body_faces)
    for (int k = 0; k < 3; ++k) incident[size_t(in.F(f, k))].push_back(f);
  const MatrixX3f normals = vertex_normals(in.V, in.F);

  std::vector<Eigen::RowVector3f> positions;
  std::vector<Eigen::Vector3i> faces;
  for (int j = 0; j < J; ++j) {
    // The part's own faces, then the faces of other joints that touch them (the overlap ring).
    std::vector<uint8_t> own_vertex(size_t(Nb), 0);
    std::vector<int32_t> part_faces;
    for (const int32_t f : body_faces) {
      if (face_joint[size_t(f)] != j) continue;
      part_faces.push_back(f);
      for (int k = 0; k < 3; ++k) own_vertex[size_t(in.F(f, k))] = 1;
    }
    if (part_faces.empty()) continue;
    std::vector<int32_t> ring;
    for (const int32_t f : part_faces)
      for (int k = 0; k < 3; ++k)
        for (const int32_t g : incident[size_t(in.F(f, k))])
          if (face_joint[size_t(g)] != j) ring.push_back(g);
    std::sort(ring.begin(), ring.end());
    ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
    part_faces.insert(part_faces.end(), ring.begin(), ring.end());
    std::vector<int32_t> copy(size_t(Nb), -1);
    const int part = out.num_parts++;
    for (const int32_t f : part_faces) {
      if (dropped[size_t(f)]) continue;
      Eigen::Vector3i face;
      for (int k = 0; k < 3; ++k) {
        const int32_t v = in.F(f, k);
        if (copy[size_t(v)] < 0) {
          copy[size_t(v)] = int32_t(positions.size());
          const float inset = own_vertex[size_t(v)] ? 0.0f : options.overlap_inset;
          positions.push_back(in.V.row(v) - inset * normals.row(v));
          out.source.push_back(v);
          out.part.push_back(part);
        }
        face[k] = copy[size_t(v)];
      }
      faces.push_back(face);
    }
  }
  if (options.head_cap) {
    // A dome over the head part: centred on its vertices' centroid, radius cap_scale times their median
    // distance to it; the top and back of the sphere (above a tenth of the radius below the centre, and
    // not the front half of the face).
    std::vector<int32_t> head_vertices;
    for (int v = 0; v < Nb; ++v) {
      Eigen::Index best = 0;
      W.row(v).maxCoeff(&best);
      if (best == head) head_vertices.push_back(v);
    }
    AMT_CHECK(!head_vertices.empty(), "open parts: expected body vertices on the head, found none");
    Eigen::RowVector3f centre = Eigen::RowVector3f::Zero();
    for (const int32_t v : head_vertices) centre += in.V.row(v);
    centre /= float(head_vertices.size());
    std::vector<float> distances;
    for (const int32_t v : head_vertices) distances.push_back((in.V.row(v) - centre).norm());
    std::nth_element(distances.begin(), distances.begin() + distances.size() / 2, distances.end());
    const float radius = options.cap_scale * distances[distances.size() / 2];
    const TriMesh sphere = uv_sphere(centre.transpose(), radius, 40, 20);
    std::vector<int32_t> copy(size_t(sphere.num_vertices()), -1);
    const int part = out.num_parts++;
    const auto on_cap = [&](int v) {
      const Eigen::RowVector3f d = sphere.V.row(v) - centre;
      return d.y() > -0.1f * radius && !(d.z() > 0.4f * radius && d.y() < 0.5f * radius);
    };
    for (int f = 0; f < sphere.num_faces(); ++f) {
      if (!on_cap(sphere.F(f, 0)) || !on_cap(sphere.F(f, 1)) || !on_cap(sphere.F(f, 2))) continue;
      Eigen::Vector3i face;
      for (int k = 0; k < 3; ++k) {
        const int32_t v = sphere.F(f, k);
        if (copy[size_t(v)] < 0) {
          copy[size_t(v)] = int32_t(positions.size());
          positions.push_back(sphere.V.row(v));
          out.source.push_back(-1);
          out.part.push_back(part);
        }
        face[k] = copy[size_t(v)];
      }
      faces.push_back(face);
    }
  }
  // Garment and apparel vertices and faces, unchanged.
  const int32_t offset = int32_t(positions.size()) - Nb;
  for (int v = Nb; v < N; ++v) {
    positions.push_back(in.V.row(v));
    out.source.push_back(v);
    out.part.push_back(-1);
  }
  for (const int32_t f : other_faces) {
    Eigen::Vector3i face;
    for (int k = 0; k < 3; ++k) {
      const int32_t v = in.F(f, k);
      AMT_CHECK(v >= Nb, "open parts: expected garment faces without body vertices, found face ", f,
                " on body vertex ", v);
      face[k] = v + offset;
    }
    faces.push_back(face);
  }

  const int M = int(positions.size());
  out.mesh.V.resize(M, 3);
  out.apparel_mask.assign(size_t(M), 0);
  out.body_weights = MatrixXfR::Zero(M, J);
  for (int v = 0; v < M; ++v) {
    out.mesh.V.row(v) = positions[size_t(v)];
    const int32_t s = out.source[size_t(v)];
    if (s >= 0) {
      out.apparel_mask[size_t(v)] = dressed.apparel_mask[size_t(s)];
      out.body_weights.row(v) = W.row(s);
    } else {
      out.body_weights(v, head) = 1.0f;
    }
  }
  out.mesh.F.resize(Eigen::Index(faces.size()), 3);
  for (size_t f = 0; f < faces.size(); ++f) out.mesh.F.row(Eigen::Index(f)) = faces[f].transpose();
  return out;
}

}  // namespace amt
