#include "refit/contact.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/mesh.h"
#include "refit/aabb_tree.h"
#include "refit/assembly.h"
#include "refit/barrier.h"
#include "refit/distance.h"

namespace amt::refit {
namespace {

using Eigen::Vector3d;

Vector3d point(const Positions& x, int i) { return x.row(i).transpose(); }

bool face_has(const MatrixX3i& F, int f, int v) { return F(f, 0) == v || F(f, 1) == v || F(f, 2) == v; }

bool edges_share_vertex(const MatrixX2i& E, int a, int b) {
  return E(a, 0) == E(b, 0) || E(a, 0) == E(b, 1) || E(a, 1) == E(b, 0) || E(a, 1) == E(b, 1);
}

Aabb face_box(const CollisionMesh& mesh, const Positions& x, int f) {
  Aabb box;
  for (int k = 0; k < 3; ++k) box.extend(point(x, mesh.F(f, k)));
  return box;
}

Aabb edge_box(const CollisionMesh& mesh, const Positions& x, int e) {
  Aabb box;
  box.extend(point(x, mesh.E(e, 0)));
  box.extend(point(x, mesh.E(e, 1)));
  return box;
}

// Pairs of vertex boxes against face boxes and of edge boxes against each other, filtered by incidence
// and by the obstacle rule. Obstacle vertices and edges are queried against trees of the free faces and
// edges only, so that pairs of two obstacle primitives are never enumerated: the shrunk avatar of the
// inflation lies on its bones, where every avatar box overlaps hundreds of others.
Candidates candidates_from_boxes(const CollisionMesh& mesh, const std::vector<Aabb>& vertex_boxes,
                                 const std::vector<Aabb>& face_boxes, const std::vector<Aabb>& edge_boxes) {
  Candidates out;
  std::vector<int> hits, free_faces, free_edges;
  std::vector<Aabb> free_face_boxes, free_edge_boxes;
  for (int f = 0; f < static_cast<int>(mesh.F.rows()); ++f)
    if (!mesh.face_obstacle[f]) free_faces.push_back(f), free_face_boxes.push_back(face_boxes[f]);
  for (int e = 0; e < static_cast<int>(mesh.E.rows()); ++e)
    if (!mesh.edge_obstacle[e]) free_edges.push_back(e), free_edge_boxes.push_back(edge_boxes[e]);
  const AabbTree all_faces(face_boxes), faces_of_free(std::move(free_face_boxes));
  for (int v = 0; v < mesh.num_vertices; ++v) {
    hits.clear();
    const bool obstacle = mesh.vertex_obstacle[v];
    (obstacle ? faces_of_free : all_faces).query(vertex_boxes[v], &hits);
    for (int hit : hits) {
      const int f = obstacle ? free_faces[hit] : hit;
      if (face_has(mesh.F, f, v)) continue;
      out.point_triangle.push_back({v, f});
    }
  }
  const AabbTree edges_of_free(std::move(free_edge_boxes));
  for (int a = 0; a < static_cast<int>(mesh.E.rows()); ++a) {
    hits.clear();
    edges_of_free.query(edge_boxes[a], &hits);
    for (int hit : hits) {
      const int b = free_edges[hit];
      // Two free edges meet in both queries: keep one. An obstacle edge meets a free one only in its own.
      if ((!mesh.edge_obstacle[a] && b <= a) || edges_share_vertex(mesh.E, a, b)) continue;
      out.edge_edge.push_back({std::min(a, b), std::max(a, b)});
    }
  }
  // Deterministic order, whatever the tree's traversal order.
  std::sort(out.point_triangle.begin(), out.point_triangle.end());
  std::sort(out.edge_edge.begin(), out.edge_edge.end());
  return out;
}

// --- The constraint set: the pairs within d̂, point-triangle pairs reduced to their closest features

struct ConstraintSet {
  std::vector<std::array<int, 4>> point_face;   // (p, t0, t1, t2), closest to the face interior
  std::vector<std::array<int, 3>> point_edge;   // (p, e0, e1), e0 < e1, deduplicated
  std::vector<std::array<int, 2>> point_point;  // (p, q), deduplicated
  std::vector<std::array<int, 3>> edge_edge;    // (edge a, edge b, EdgeEdgeType)
};

ConstraintSet active_constraints(const CollisionMesh& mesh, const Positions& x, double d_hat) {
  const double s_hat = d_hat * d_hat;
  const Candidates candidates = proximity_candidates(mesh, x, d_hat);
  ConstraintSet set;
  for (const auto& [v, f] : candidates.point_triangle) {
    const int t[3] = {mesh.F(f, 0), mesh.F(f, 1), mesh.F(f, 2)};
    const Vector3d p = point(x, v), t0 = point(x, t[0]), t1 = point(x, t[1]), t2 = point(x, t[2]);
    const PointTriangleType type = point_triangle_type(p, t0, t1, t2);
    if (point_triangle_distance_sq(p, t0, t1, t2, type) >= s_hat) continue;
    switch (type) {
      case PointTriangleType::P_T: set.point_face.push_back({v, t[0], t[1], t[2]}); break;
      case PointTriangleType::P_E0:
      case PointTriangleType::P_E1:
      case PointTriangleType::P_E2: {
        const int k = static_cast<int>(type) - static_cast<int>(PointTriangleType::P_E0);
        const int a = t[k], b = t[(k + 1) % 3];
        set.point_edge.push_back({v, std::min(a, b), std::max(a, b)});
        break;
      }
      default: set.point_point.push_back({v, t[static_cast<int>(type)]});
    }
  }
  auto dedup = [](auto& list) {
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
  };
  dedup(set.point_edge);
  dedup(set.point_point);
  for (const auto& [a, b] : candidates.edge_edge) {
    const Vector3d ea0 = point(x, mesh.E(a, 0)), ea1 = point(x, mesh.E(a, 1));
    const Vector3d eb0 = point(x, mesh.E(b, 0)), eb1 = point(x, mesh.E(b, 1));
    const EdgeEdgeType type = edge_edge_type(ea0, ea1, eb0, eb1);
    if (edge_edge_distance_sq(ea0, ea1, eb0, eb1, type) >= s_hat) continue;
    set.edge_edge.push_back({a, b, static_cast<int>(type)});
  }
  return set;
}

// κ b(s(x)): value, gradient κ b' ∇s, Hessian κ (b'' ∇s ∇sᵀ + b' ∇²s).
Derivatives12 barrier_of(const Derivatives12& s, double s_hat, double stiffness) {
  const ScalarDerivatives b = barrier(s.value, s_hat);
  Derivatives12 out;
  out.value = stiffness * b.value;
  out.gradient = stiffness * b.first * s.gradient;
  out.hessian = stiffness * (b.second * s.gradient * s.gradient.transpose() + b.first * s.hessian);
  return out;
}

}  // namespace

CollisionMesh make_collision_mesh(const Positions& rest, const MatrixX3i& F, std::vector<uint8_t> obstacle) {
  CollisionMesh mesh;
  mesh.num_vertices = static_cast<int>(rest.rows());
  AMT_CHECK(obstacle.empty() || static_cast<int>(obstacle.size()) == mesh.num_vertices, "collision mesh: ",
            obstacle.size(), " obstacle flags for ", mesh.num_vertices, " vertices");
  for (int f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      AMT_CHECK(F(f, k) >= 0 && F(f, k) < mesh.num_vertices, "collision mesh: face ", f, " has vertex index ",
                F(f, k), ", expected one in [0, ", mesh.num_vertices, ")");
  mesh.F = F;
  mesh.E = unique_edges(F);
  mesh.vertex_obstacle = obstacle.empty() ? std::vector<uint8_t>(mesh.num_vertices, 0) : std::move(obstacle);
  mesh.face_obstacle.resize(F.rows());
  for (int f = 0; f < F.rows(); ++f)
    mesh.face_obstacle[f] =
        mesh.vertex_obstacle[F(f, 0)] && mesh.vertex_obstacle[F(f, 1)] && mesh.vertex_obstacle[F(f, 2)];
  mesh.edge_obstacle.resize(mesh.E.rows());
  mesh.edge_rest_length_sq.resize(mesh.E.rows());
  for (int e = 0; e < mesh.E.rows(); ++e) {
    mesh.edge_obstacle[e] = mesh.vertex_obstacle[mesh.E(e, 0)] && mesh.vertex_obstacle[mesh.E(e, 1)];
    mesh.edge_rest_length_sq[e] = (rest.row(mesh.E(e, 0)) - rest.row(mesh.E(e, 1))).squaredNorm();
  }
  return mesh;
}

CollisionMesh make_garment_avatar_mesh(const Positions& garment_rest, const MatrixX3i& F_garment,
                                       const Positions& avatar_rest, const MatrixX3i& F_avatar) {
  const int n_g = static_cast<int>(garment_rest.rows()), n_a = static_cast<int>(avatar_rest.rows());
  Positions rest(n_g + n_a, 3);
  rest << garment_rest, avatar_rest;
  MatrixX3i F(F_garment.rows() + F_avatar.rows(), 3);
  F << F_garment, (F_avatar.array() + n_g).matrix();
  std::vector<uint8_t> obstacle(n_g + n_a, 0);
  std::fill(obstacle.begin() + n_g, obstacle.end(), 1);
  return make_collision_mesh(rest, F, std::move(obstacle));
}

Candidates proximity_candidates(const CollisionMesh& mesh, const Positions& x, double inflation) {
  std::vector<Aabb> vertex_boxes(mesh.num_vertices), face_boxes(mesh.F.rows()), edge_boxes(mesh.E.rows());
  for (int v = 0; v < mesh.num_vertices; ++v) {
    vertex_boxes[v].extend(point(x, v));
    vertex_boxes[v].inflate(inflation);
  }
  for (int f = 0; f < mesh.F.rows(); ++f) face_boxes[f] = face_box(mesh, x, f);
  for (int e = 0; e < mesh.E.rows(); ++e) {
    edge_boxes[e] = edge_box(mesh, x, e);
    edge_boxes[e].inflate(0.5 * inflation);  // two boxes grown by half each: overlap within `inflation`
  }
  return candidates_from_boxes(mesh, vertex_boxes, face_boxes, edge_boxes);
}

Candidates motion_candidates(const CollisionMesh& mesh, const Positions& x, const Positions& dx) {
  const Positions y = x + dx;
  std::vector<Aabb> vertex_boxes(mesh.num_vertices), face_boxes(mesh.F.rows()), edge_boxes(mesh.E.rows());
  for (int v = 0; v < mesh.num_vertices; ++v) {
    vertex_boxes[v].extend(point(x, v));
    vertex_boxes[v].extend(point(y, v));
  }
  for (int f = 0; f < mesh.F.rows(); ++f) {
    face_boxes[f] = face_box(mesh, x, f);
    const Aabb end = face_box(mesh, y, f);
    face_boxes[f].extend(end.min);
    face_boxes[f].extend(end.max);
  }
  for (int e = 0; e < mesh.E.rows(); ++e) {
    edge_boxes[e] = edge_box(mesh, x, e);
    const Aabb end = edge_box(mesh, y, e);
    edge_boxes[e].extend(end.min);
    edge_boxes[e].extend(end.max);
  }
  return candidates_from_boxes(mesh, vertex_boxes, face_boxes, edge_boxes);
}

double min_distance_sq(const CollisionMesh& mesh, const Positions& x, const Candidates& candidates) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& [v, f] : candidates.point_triangle)
    best = std::min(best, point_triangle_distance_sq(point(x, v), point(x, mesh.F(f, 0)), point(x, mesh.F(f, 1)),
                                                     point(x, mesh.F(f, 2))));
  for (const auto& [a, b] : candidates.edge_edge)
    best = std::min(best, edge_edge_distance_sq(point(x, mesh.E(a, 0)), point(x, mesh.E(a, 1)),
                                                point(x, mesh.E(b, 0)), point(x, mesh.E(b, 1))));
  return best;
}

double max_collision_free_step(const CollisionMesh& mesh, const Positions& x, const Positions& dx,
                               const CcdOptions& options) {
  const Candidates candidates = motion_candidates(mesh, x, dx);
  double t = 1.0;
  double toi;
  // Each query only needs to look up to the smallest time found so far (t_c of Algorithm 1).
  for (const auto& [v, f] : candidates.point_triangle) {
    const int a = mesh.F(f, 0), b = mesh.F(f, 1), c = mesh.F(f, 2);
    if (point_triangle_ccd(point(x, v), point(x, a), point(x, b), point(x, c), point(dx, v), point(dx, a),
                           point(dx, b), point(dx, c), t, &toi, options))
      t = std::min(t, toi);
  }
  for (const auto& [ea, eb] : candidates.edge_edge) {
    const int a0 = mesh.E(ea, 0), a1 = mesh.E(ea, 1), b0 = mesh.E(eb, 0), b1 = mesh.E(eb, 1);
    if (edge_edge_ccd(point(x, a0), point(x, a1), point(x, b0), point(x, b1), point(dx, a0), point(dx, a1),
                      point(dx, b0), point(dx, b1), t, &toi, options))
      t = std::min(t, toi);
  }
  return t;
}

BarrierPotential::BarrierPotential(const CollisionMesh& mesh, double d_hat, double stiffness)
    : mesh_(mesh), d_hat_(d_hat), stiffness_(stiffness) {
  AMT_CHECK(d_hat > 0.0 && std::isfinite(d_hat), "barrier: d_hat ", d_hat, ", expected a positive distance");
  AMT_CHECK(stiffness > 0.0 && std::isfinite(stiffness), "barrier: stiffness ", stiffness, ", expected > 0");
}

double BarrierPotential::value(const Positions& x) const { return derivatives(x, nullptr, nullptr, false); }

double BarrierPotential::derivatives(const Positions& x, Eigen::VectorXd* gradient,
                                     std::vector<Eigen::Triplet<double>>* hessian, bool project_psd) const {
  const double s_hat = d_hat_ * d_hat_;
  const ConstraintSet set = active_constraints(mesh_, x, d_hat_);
  const bool want = gradient || hessian;
  double energy = 0.0;
  // A point-feature constraint: the piece `type` of the point-triangle distance over the first n slots.
  auto point_constraint = [&](const int* v, int n, PointTriangleType type) {
    const Vector3d q[4] = {point(x, v[0]), point(x, v[1]), point(x, v[n > 2 ? 2 : 1]), point(x, v[n > 3 ? 3 : 1])};
    if (!want) {
      energy += stiffness_ * barrier(point_triangle_distance_sq(q[0], q[1], q[2], q[3], type), s_hat).value;
      return;
    }
    const Derivatives12 b =
        barrier_of(point_triangle_distance_sq_derivatives(q[0], q[1], q[2], q[3], type), s_hat, stiffness_);
    energy += b.value;
    add_element(v, n, b.gradient, b.hessian, project_psd, gradient, hessian);
  };
  for (const auto& c : set.point_face) point_constraint(c.data(), 4, PointTriangleType::P_T);
  for (const auto& c : set.point_edge) point_constraint(c.data(), 3, PointTriangleType::P_E0);
  for (const auto& c : set.point_point) point_constraint(c.data(), 2, PointTriangleType::P_T0);
  for (const auto& [a, b, type_index] : set.edge_edge) {
    const int v[4] = {mesh_.E(a, 0), mesh_.E(a, 1), mesh_.E(b, 0), mesh_.E(b, 1)};
    const Vector3d q[4] = {point(x, v[0]), point(x, v[1]), point(x, v[2]), point(x, v[3])};
    const auto type = static_cast<EdgeEdgeType>(type_index);
    const double eps_x = edge_edge_mollifier_threshold(mesh_.edge_rest_length_sq[a], mesh_.edge_rest_length_sq[b]);
    const Mollifier m = edge_edge_mollifier(q[0], q[1], q[2], q[3], eps_x);
    if (!want) {
      energy += stiffness_ * m.value * barrier(edge_edge_distance_sq(q[0], q[1], q[2], q[3], type), s_hat).value;
      continue;
    }
    const Derivatives12 bd =
        barrier_of(edge_edge_distance_sq_derivatives(q[0], q[1], q[2], q[3], type), s_hat, stiffness_);
    Derivatives12 e;
    // (m b)'' = m b'' + b m'' + ∇m ∇bᵀ + ∇b ∇mᵀ.
    e.value = m.value * bd.value;
    e.gradient = m.value * bd.gradient + bd.value * m.gradient;
    e.hessian = m.value * bd.hessian + bd.value * m.hessian + m.gradient * bd.gradient.transpose() +
                bd.gradient * m.gradient.transpose();
    energy += e.value;
    add_element(v, 4, e.gradient, e.hessian, project_psd, gradient, hessian);
  }
  return energy;
}

}  // namespace amt::refit
