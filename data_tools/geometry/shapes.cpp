#include "data_tools/geometry/shapes.h"

#include <algorithm>
#include <cmath>

#include "data_tools/geometry/error.h"

namespace amt {

namespace {

// Rings of vertices along the z axis of a local frame, closed by a pole vertex at each end.
// ring_z[k], ring_r[k]: height and radius of ring k. Returns the mesh in local coordinates.
TriMesh lathe(float bottom_z, float top_z, const std::vector<float>& ring_z, const std::vector<float>& ring_r,
              int segments) {
  const int rings = static_cast<int>(ring_z.size());
  TriMesh m;
  m.V.resize(2 + rings * segments, 3);
  m.V.row(0) << 0, 0, bottom_z;
  for (int k = 0; k < rings; ++k) {
    for (int s = 0; s < segments; ++s) {
      const float a = 2.0f * float(M_PI) * s / segments;
      m.V.row(1 + k * segments + s) << ring_r[k] * std::cos(a), ring_r[k] * std::sin(a), ring_z[k];
    }
  }
  const int top = 1 + rings * segments;
  m.V.row(top) << 0, 0, top_z;
  m.F.resize(2 * segments * rings, 3);
  int f = 0;
  auto at = [&](int k, int s) { return 1 + k * segments + (s % segments); };
  for (int s = 0; s < segments; ++s) m.F.row(f++) << 0, at(0, s + 1), at(0, s);  // bottom fan, facing -z
  for (int k = 0; k + 1 < rings; ++k) {
    for (int s = 0; s < segments; ++s) {
      m.F.row(f++) << at(k, s), at(k, s + 1), at(k + 1, s + 1);
      m.F.row(f++) << at(k, s), at(k + 1, s + 1), at(k + 1, s);
    }
  }
  for (int s = 0; s < segments; ++s) m.F.row(f++) << top, at(rings - 1, s), at(rings - 1, s + 1);
  return m;
}

// Moves a mesh built along +z at the origin onto the segment starting at `a` with direction `dir`.
void place(TriMesh& m, const Eigen::Vector3f& a, const Eigen::Vector3f& dir) {
  const Eigen::Matrix3f R =
      Eigen::Quaternionf::FromTwoVectors(Eigen::Vector3f::UnitZ(), dir.norm() > 0 ? dir : Eigen::Vector3f::UnitZ())
          .toRotationMatrix();
  m.V = (m.V * R.transpose()).rowwise() + a.transpose();
}

}  // namespace

TriMesh uv_sphere(const Eigen::Vector3f& center, float radius, int segments, int rings) {
  AMT_CHECK(segments >= 3 && rings >= 2, "uv_sphere: expected segments >= 3 and rings >= 2, found ", segments, " and ",
            rings);
  std::vector<float> z, r;
  for (int k = 1; k < rings; ++k) {
    const float phi = -float(M_PI) / 2 + float(M_PI) * k / rings;
    z.push_back(radius * std::sin(phi));
    r.push_back(radius * std::cos(phi));
  }
  TriMesh m = lathe(-radius, radius, z, r, segments);
  m.V.rowwise() += center.transpose();
  return m;
}

TriMesh capsule(const Eigen::Vector3f& a, const Eigen::Vector3f& b, float radius, int segments, int hemisphere_rings,
                int length_rings) {
  AMT_CHECK(segments >= 3 && hemisphere_rings >= 1 && length_rings >= 1,
            "capsule: expected segments >= 3, hemisphere_rings >= 1, length_rings >= 1");
  const float length = (b - a).norm();
  std::vector<float> z, r;
  for (int k = 1; k <= hemisphere_rings; ++k) {  // bottom hemisphere, up to its equator
    const float phi = -float(M_PI) / 2 + float(M_PI) / 2 * k / hemisphere_rings;
    z.push_back(radius * std::sin(phi));
    r.push_back(radius * std::cos(phi));
  }
  for (int k = 1; k < length_rings; ++k) {  // along the cylinder
    z.push_back(length * k / length_rings);
    r.push_back(radius);
  }
  for (int k = 0; k < hemisphere_rings; ++k) {  // top hemisphere, from its equator
    const float phi = float(M_PI) / 2 * k / hemisphere_rings;
    z.push_back(length + radius * std::sin(phi));
    r.push_back(radius * std::cos(phi));
  }
  TriMesh m = lathe(-radius, length + radius, z, r, segments);
  place(m, a, b - a);
  return m;
}

TriMesh grid(int nx, int ny, float spacing) {
  AMT_CHECK(nx >= 2 && ny >= 2, "grid: expected at least 2 x 2 vertices, found ", nx, " x ", ny);
  TriMesh m;
  m.V.resize(nx * ny, 3);
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) m.V.row(j * nx + i) << i * spacing, j * spacing, 0;
  }
  m.F.resize(2 * (nx - 1) * (ny - 1), 3);
  int f = 0;
  for (int j = 0; j + 1 < ny; ++j) {
    for (int i = 0; i + 1 < nx; ++i) {
      const int v = j * nx + i;
      m.F.row(f++) << v, v + 1, v + nx + 1;
      m.F.row(f++) << v, v + nx + 1, v + nx;
    }
  }
  return m;
}

TriMesh merge_meshes(const std::vector<TriMesh>& parts, std::vector<int32_t>* part_of_vertex) {
  Eigen::Index nv = 0, nf = 0;
  for (const TriMesh& p : parts) nv += p.V.rows(), nf += p.F.rows();
  TriMesh m;
  m.V.resize(nv, 3);
  m.F.resize(nf, 3);
  if (part_of_vertex) part_of_vertex->resize(static_cast<size_t>(nv));
  Eigen::Index v = 0, f = 0;
  for (size_t k = 0; k < parts.size(); ++k) {
    const TriMesh& p = parts[k];
    m.V.middleRows(v, p.V.rows()) = p.V;
    m.F.middleRows(f, p.F.rows()) = p.F.array() + static_cast<int32_t>(v);
    if (part_of_vertex) std::fill_n(part_of_vertex->begin() + v, p.V.rows(), static_cast<int32_t>(k));
    v += p.V.rows();
    f += p.F.rows();
  }
  return m;
}

TriMesh capsule_character(const MatrixX3f& rest_joints, const std::vector<int32_t>& parents, int target_vertices,
                          std::vector<int32_t>* joint_of_vertex) {
  const int bones = static_cast<int>(parents.size()) - 1;
  AMT_CHECK(bones >= 1 && target_vertices >= 100, "capsule_character: expected a skeleton with bones and at least 100 "
            "vertices, found ", bones, " bones and ", target_vertices, " vertices");
  // Vertices per capsule: 2 + segments (2 h + l - 1). Pick segments ~ sqrt of the part's budget,
  // h = segments / 4 hemisphere rings, and fill the rest with rings along the bone.
  const int per_part = target_vertices / (bones + 1);
  const int segments = std::max(4, static_cast<int>(std::sqrt(per_part / 1.5)) & ~1);
  const int h = std::max(1, segments / 4);
  const int l = std::max(1, (per_part - 2) / segments - 2 * h + 1);
  std::vector<TriMesh> parts;
  for (size_t j = 1; j < parents.size(); ++j) {
    const Eigen::Vector3f a = rest_joints.row(parents[j]).transpose(), b = rest_joints.row(j).transpose();
    parts.push_back(capsule(a, b, std::max(0.03f, 0.15f * (b - a).norm()), segments, h, l));
  }
  // The head: a sphere above the last joint in the chain from the root with the highest position.
  Eigen::Index top = 0;
  rest_joints.col(1).maxCoeff(&top);
  const int rings = std::max(2, 2 * h + l);  // the same vertex count as a capsule
  parts.push_back(uv_sphere(rest_joints.row(top).transpose() + Eigen::Vector3f(0, 0.1f, 0), 0.1f, segments, rings));
  std::vector<int32_t> part;
  TriMesh m = merge_meshes(parts, &part);
  if (joint_of_vertex) {
    joint_of_vertex->resize(part.size());
    for (size_t i = 0; i < part.size(); ++i) {
      const int k = part[i];
      (*joint_of_vertex)[i] = k < bones ? parents[k + 1] : static_cast<int32_t>(top);
    }
  }
  return m;
}

}  // namespace amt
