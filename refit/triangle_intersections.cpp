#include "refit/triangle_intersections.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "data_tools/geometry/error.h"
#include "refit/aabb_tree.h"

namespace amt::refit {
namespace {

using Eigen::Vector3d;

// Six times the signed volume of the tetrahedron (a, b, c, d).
double orient(const Vector3d& a, const Vector3d& b, const Vector3d& c, const Vector3d& d) {
  return (b - a).cross(c - a).dot(d - a);
}

// The segment (p, q) passes through the triangle (a, b, c): its ends on opposite sides of (or one on)
// the plane, and the line through it on the same side of all three edges (sign tests on signed volumes).
// Volumes within rounding of zero (10⁻¹² of the cube of the configuration's size) count as zero, so
// that coplanar neighbours, common on flat parts of a garment, are never taken for crossings.
bool segment_crosses_triangle(const Vector3d& p, const Vector3d& q, const Vector3d& a, const Vector3d& b,
                              const Vector3d& c) {
  const double size = std::max({(b - a).norm(), (c - a).norm(), (p - a).norm(), (q - a).norm()});
  const double tolerance = 1e-12 * size * size * size;
  auto snap = [tolerance](double volume) { return std::abs(volume) <= tolerance ? 0.0 : volume; };
  const double sp = snap(orient(a, b, c, p)), sq = snap(orient(a, b, c, q));
  if ((sp > 0 && sq > 0) || (sp < 0 && sq < 0) || (sp == 0 && sq == 0)) return false;
  const double u = orient(p, q, a, b), v = orient(p, q, b, c), w = orient(p, q, c, a);
  return (u >= 0 && v >= 0 && w >= 0) || (u <= 0 && v <= 0 && w <= 0);
}

}  // namespace

std::vector<std::array<int, 2>> crossing_triangle_pairs(const CollisionMesh& mesh, const Positions& x,
                                                        int max_pairs) {
  const int m = static_cast<int>(mesh.F.rows());
  std::vector<Aabb> boxes(m);
  for (int f = 0; f < m; ++f)
    for (int k = 0; k < 3; ++k) boxes[f].extend(x.row(mesh.F(f, k)).transpose());
  const AabbTree tree(boxes);
  std::vector<std::array<int, 2>> out;
  std::vector<int> hits;
  for (int f = 0; f < m; ++f) {
    hits.clear();
    tree.query(boxes[f], &hits);
    std::sort(hits.begin(), hits.end());
    const Vector3d a[3] = {x.row(mesh.F(f, 0)), x.row(mesh.F(f, 1)), x.row(mesh.F(f, 2))};
    for (int g : hits) {
      if (g <= f || (mesh.face_obstacle[f] && mesh.face_obstacle[g])) continue;
      bool shares = false;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) shares = shares || mesh.F(f, i) == mesh.F(g, j);
      if (shares) continue;
      const Vector3d b[3] = {x.row(mesh.F(g, 0)), x.row(mesh.F(g, 1)), x.row(mesh.F(g, 2))};
      bool crosses = false;
      for (int k = 0; k < 3 && !crosses; ++k)
        crosses = segment_crosses_triangle(a[k], a[(k + 1) % 3], b[0], b[1], b[2]) ||
                  segment_crosses_triangle(b[k], b[(k + 1) % 3], a[0], a[1], a[2]);
      if (!crosses) continue;
      out.push_back({f, g});
      if (max_pairs > 0 && static_cast<int>(out.size()) >= max_pairs) return out;
    }
  }
  return out;
}

void check_garment_avatar_start(const CollisionMesh& mesh, const Positions& x, int num_garment_faces,
                                const std::string& stage, const std::string& avatar) {
  const auto crossing = crossing_triangle_pairs(mesh, x);
  if (crossing.empty()) return;
  const auto [f, g] = crossing[0];  // f < g: f is a garment face (avatar pairs are left out)
  if (g < num_garment_faces)
    fail(stage, ": garment faces ", f, " and ", g, " cross each other; the garment must be free of self-intersections");
  fail(stage, ": garment face ", f, " crosses ", avatar, " face ", g - num_garment_faces,
       "; the garment must start intersection-free with it");
}

}  // namespace amt::refit
